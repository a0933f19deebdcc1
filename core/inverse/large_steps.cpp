// Large Steps: the Laplacian, its factorization (Eigen's SimplicialLDLT, whose fill-reducing
// ordering and arithmetic are the same on every run: the same bits each time) and the solves.
#include "core/inverse/large_steps.h"

#include <algorithm>
#include <array>
#include <map>
#include <utility>

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

LargeSteps::LargeSteps(const std::vector<float>& positions, const std::vector<unsigned>& triangles,
                       double lambda)
    : m_lambda(lambda), m_solver(std::make_unique<Solver>()) {
    if (!(lambda >= 0.0)) throw Error("large steps: lambda must be at least 0");
    const std::size_t n = positions.size() / 3;
    // weld: one point per distinct position, numbered in order of first appearance
    std::map<std::array<float, 3>, unsigned> ids;
    m_weld.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        const std::array<float, 3> key{positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]};
        const auto [it, added] = ids.emplace(key, static_cast<unsigned>(ids.size()));
        m_weld[i] = it->second;
    }
    m_points = ids.size();
    // L: -1 for each distinct edge between points, the degree on the diagonal
    std::vector<std::pair<unsigned, unsigned>> edges;
    for (std::size_t t = 0; t + 2 < triangles.size(); t += 3)
        for (int k = 0; k < 3; ++k) {
            const unsigned a = triangles[t + k], b = triangles[t + (k + 1) % 3];
            if (a >= n || b >= n) throw Error("large steps: a vertex index is out of range");
            const unsigned p = m_weld[a], q = m_weld[b];
            if (p != q) edges.emplace_back(std::min(p, q), std::max(p, q));
        }
    std::sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
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

Eigen::MatrixXd as_rows(const std::vector<float>& v, std::size_t rows) {
    Eigen::MatrixXd m(rows, 3);
    for (std::size_t i = 0; i < rows; ++i)
        for (int c = 0; c < 3; ++c) m(Eigen::Index(i), c) = v[3 * i + std::size_t(c)];
    return m;
}

} // namespace

std::vector<float> LargeSteps::to_differential(const std::vector<float>& x) const {
    if (x.size() != 3 * vertices()) throw Error("large steps: positions of another mesh");
    Eigen::MatrixXd xp(m_points, 3);
    std::vector<bool> seen(m_points, false);
    for (std::size_t i = 0; i < vertices(); ++i) {
        if (seen[m_weld[i]]) continue;
        seen[m_weld[i]] = true;
        for (int c = 0; c < 3; ++c) xp(m_weld[i], c) = x[3 * i + std::size_t(c)];
    }
    const Eigen::MatrixXd u = m_solver->matrix * xp;
    std::vector<float> out(3 * m_points);
    for (std::size_t p = 0; p < m_points; ++p)
        for (int c = 0; c < 3; ++c) out[3 * p + std::size_t(c)] = float(u(Eigen::Index(p), c));
    return out;
}

std::vector<float> LargeSteps::from_differential(const std::vector<float>& u) const {
    if (u.size() != 3 * m_points) throw Error("large steps: differential coordinates of another mesh");
    const Eigen::MatrixXd xp = m_solver->ldlt.solve(as_rows(u, m_points));
    std::vector<float> out(3 * vertices());
    for (std::size_t i = 0; i < vertices(); ++i)
        for (int c = 0; c < 3; ++c) out[3 * i + std::size_t(c)] = float(xp(m_weld[i], c));
    return out;
}

std::vector<float> LargeSteps::gradient(const std::vector<float>& g) const {
    if (g.size() != 3 * vertices()) throw Error("large steps: a gradient of another mesh");
    Eigen::MatrixXd gp = Eigen::MatrixXd::Zero(Eigen::Index(m_points), 3);
    for (std::size_t i = 0; i < vertices(); ++i)
        for (int c = 0; c < 3; ++c) gp(m_weld[i], c) += g[3 * i + std::size_t(c)];
    const Eigen::MatrixXd gu = m_solver->ldlt.solve(gp);
    std::vector<float> out(3 * m_points);
    for (std::size_t p = 0; p < m_points; ++p)
        for (int c = 0; c < 3; ++c) out[3 * p + std::size_t(c)] = float(gu(Eigen::Index(p), c));
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
