// Large Steps: the Laplacian, its factorization (Eigen's SimplicialLDLT, whose fill-reducing
// ordering and arithmetic are the same on every run: the same bits each time) and the solves.
#include "core/inverse/large_steps.h"

#include <algorithm>
#include <array>
#include <map>
#include <utility>
#include <vector>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "runtime/error.h"

namespace tandem {

struct LargeSteps::Solver {
    Eigen::SparseMatrix<double> matrix;
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
};

LargeSteps::~LargeSteps() = default;
LargeSteps::LargeSteps(LargeSteps&&) noexcept = default;
LargeSteps& LargeSteps::operator=(LargeSteps&&) noexcept = default;

namespace {

std::vector<std::pair<unsigned, unsigned>> unique_edges(std::vector<std::pair<unsigned, unsigned>> e) {
    std::sort(e.begin(), e.end());
    e.erase(std::unique(e.begin(), e.end()), e.end());
    return e;
}

/// Each vertex's point: one per distinct position, numbered in order of first appearance.
std::vector<unsigned> weld(const std::vector<float>& positions) {
    std::map<std::array<float, 3>, unsigned> ids;
    std::vector<unsigned> out(positions.size() / 3);
    for (std::size_t i = 0; i < out.size(); ++i) {
        const std::array<float, 3> key{positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]};
        out[i] = ids.emplace(key, static_cast<unsigned>(ids.size())).first->second;
    }
    return out;
}

/// The distinct edges between points of `triangles` (vertex indices; `points` each vertex's).
std::vector<std::pair<unsigned, unsigned>> mesh_edges(const std::vector<unsigned>& triangles,
                                                      const std::vector<unsigned>& points) {
    std::vector<std::pair<unsigned, unsigned>> edges;
    for (std::size_t t = 0; t + 2 < triangles.size(); t += 3)
        for (int k = 0; k < 3; ++k) {
            const unsigned a = triangles[t + k], b = triangles[t + (k + 1) % 3];
            if (a >= points.size() || b >= points.size())
                throw Error("large steps: a vertex index is out of range");
            const unsigned p = points[a], q = points[b];
            if (p != q) edges.emplace_back(std::min(p, q), std::max(p, q));
        }
    return unique_edges(std::move(edges));
}

std::size_t count_points(const std::vector<unsigned>& weld) {
    return weld.empty() ? 0 : *std::max_element(weld.begin(), weld.end()) + std::size_t(1);
}

} // namespace

LargeSteps::LargeSteps(const std::vector<float>& positions, const std::vector<unsigned>& triangles,
                       double lambda)
    : LargeSteps(lambda, weld(positions), 3) {
    factorize(mesh_edges(triangles, m_weld));
}

LargeSteps LargeSteps::image(unsigned width, unsigned height, unsigned channels, double lambda) {
    if (width == 0 || height == 0 || channels == 0) throw Error("large steps: an empty image");
    std::vector<std::pair<unsigned, unsigned>> edges;
    for (unsigned y = 0; y < height; ++y)
        for (unsigned x = 0; x < width; ++x) {
            const unsigned i = y * width + x;
            if (x + 1 < width) edges.emplace_back(i, i + 1);
            if (y + 1 < height) edges.emplace_back(i, i + width);
        }
    std::vector<unsigned> texels(std::size_t(width) * height);
    for (std::size_t i = 0; i < texels.size(); ++i) texels[i] = static_cast<unsigned>(i);
    LargeSteps out(lambda, std::move(texels), channels);
    out.factorize(unique_edges(std::move(edges)));
    return out;
}

LargeSteps::LargeSteps(double lambda, std::vector<unsigned> weld, unsigned channels)
    : m_lambda(lambda), m_channels(channels), m_weld(std::move(weld)),
      m_points(count_points(m_weld)), m_solver(std::make_unique<Solver>()) {
    if (!(lambda >= 0.0)) throw Error("large steps: lambda must be at least 0");
}

void LargeSteps::factorize(const std::vector<std::pair<unsigned, unsigned>>& edges) {
    const double lambda = m_lambda;
    // L: -1 for each distinct edge between points, the degree on the diagonal
    std::vector<double> degree(m_points, 0.0);
    std::vector<Eigen::Triplet<double>> entries;
    for (const auto& [p, q] : edges) {
        entries.emplace_back(p, q, -lambda);
        entries.emplace_back(q, p, -lambda);
        degree[p] += 1.0;
        degree[q] += 1.0;
    }
    for (std::size_t p = 0; p < m_points; ++p)
        entries.emplace_back(int(p), int(p), 1.0 + lambda * degree[p]);
    Solver& s = *m_solver;
    s.matrix.resize(int(m_points), int(m_points));
    s.matrix.setFromTriplets(entries.begin(), entries.end());
    s.ldlt.compute(s.matrix);
    if (s.ldlt.info() != Eigen::Success) throw Error("large steps: the factorization failed");
}

namespace {

Eigen::MatrixXd as_rows(const std::vector<float>& v, std::size_t rows, unsigned cols) {
    Eigen::MatrixXd m(rows, cols);
    for (std::size_t i = 0; i < rows; ++i)
        for (unsigned c = 0; c < cols; ++c) m(Eigen::Index(i), c) = v[cols * i + c];
    return m;
}

} // namespace

std::vector<float> LargeSteps::to_differential(const std::vector<float>& x) const {
    if (x.size() != std::size_t(m_channels) * vertices()) throw Error("large steps: positions of another mesh");
    Eigen::MatrixXd xp(m_points, m_channels);
    std::vector<bool> seen(m_points, false);
    for (std::size_t i = 0; i < vertices(); ++i) {
        if (seen[m_weld[i]]) continue;
        seen[m_weld[i]] = true;
        for (unsigned c = 0; c < m_channels; ++c) xp(m_weld[i], c) = x[m_channels * i + c];
    }
    const Eigen::MatrixXd u = m_solver->matrix * xp;
    std::vector<float> out(std::size_t(m_channels) * m_points);
    for (std::size_t p = 0; p < m_points; ++p)
        for (unsigned c = 0; c < m_channels; ++c) out[m_channels * p + c] = float(u(Eigen::Index(p), c));
    return out;
}

std::vector<float> LargeSteps::from_differential(const std::vector<float>& u) const {
    if (u.size() != std::size_t(m_channels) * m_points) throw Error("large steps: differential coordinates of another mesh");
    const Eigen::MatrixXd xp = m_solver->ldlt.solve(as_rows(u, m_points, m_channels));
    std::vector<float> out(std::size_t(m_channels) * vertices());
    for (std::size_t i = 0; i < vertices(); ++i)
        for (unsigned c = 0; c < m_channels; ++c) out[m_channels * i + c] = float(xp(m_weld[i], c));
    return out;
}

std::vector<float> LargeSteps::gradient(const std::vector<float>& g) const {
    if (g.size() != std::size_t(m_channels) * vertices()) throw Error("large steps: a gradient of another mesh");
    Eigen::MatrixXd gp = Eigen::MatrixXd::Zero(Eigen::Index(m_points), m_channels);
    for (std::size_t i = 0; i < vertices(); ++i)
        for (unsigned c = 0; c < m_channels; ++c) gp(m_weld[i], c) += g[m_channels * i + c];
    const Eigen::MatrixXd gu = m_solver->ldlt.solve(gp);
    std::vector<float> out(std::size_t(m_channels) * m_points);
    for (std::size_t p = 0; p < m_points; ++p)
        for (unsigned c = 0; c < m_channels; ++c) out[m_channels * p + c] = float(gu(Eigen::Index(p), c));
    return out;
}

std::vector<double> LargeSteps::dense_matrix() const {
    const Eigen::MatrixXd d(m_solver->matrix);
    std::vector<double> out(m_points * m_points);
    for (std::size_t r = 0; r < m_points; ++r)
        for (std::size_t c = 0; c < m_points; ++c) out[r * m_points + c] = d(Eigen::Index(r), Eigen::Index(c));
    return out;
}

} // namespace tandem
