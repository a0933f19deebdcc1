// Large Steps for vertex positions ("Large Steps in Inverse Rendering of Geometry", Nicolet,
// Jacobson, Jakob, SIGGRAPH Asia 2021, Sec. 4-5): an optimizer steps the differential coordinates
// u = (I + lambda L) x instead of the positions x, L the mesh's combinatorial Laplacian; the
// positions are recovered by a sparse Cholesky solve (Eigen's). A gradient with respect to x
// becomes one with respect to u by the same solve ((I + lambda L) is symmetric), which spreads
// each vertex's gradient smoothly over its neighbours: steps stay smooth and meshes do not tangle.
// The same preconditioning serves a texture, L then the texel grid's Laplacian, as "Recursive
// Control Variates for Inverse Rendering" (Nicolet, Rousselle, Novák, Keller, Jakob, Müller,
// SIGGRAPH 2023, Sec. 6) does for its texture experiments.
#pragma once

#include <memory>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

namespace tandem {

class LargeSteps {
public:
    /// The parametrization of a mesh of `positions` (x y z each) and `triangles` (three vertex
    /// indices each). Vertices at the same position are one point (a cube's faces split them, as
    /// Mitsuba's largesteps fuses them): they share one u, and their gradients add. lambda: the
    /// smoothing weight (Mitsuba's default, 19). Throws Error for lambda < 0, an index out of
    /// range, or a matrix the factorization rejects.
    LargeSteps(const std::vector<float>& positions, const std::vector<unsigned>& triangles,
               double lambda = 19.0);
    /// The parametrization of an image of width x height texels of `channels` floats each (rows
    /// of texels, channels fastest, as a bitmap parameter's): L the grid's combinatorial
    /// Laplacian, each texel joined to its four neighbours (none across the borders: a texture
    /// that wraps is still smoothed as a sheet). Each texel is a point of its own. Throws Error
    /// for lambda < 0 or an empty image.
    static LargeSteps image(unsigned width, unsigned height, unsigned channels, double lambda = 19.0);
    ~LargeSteps();
    LargeSteps(LargeSteps&&) noexcept;
    LargeSteps& operator=(LargeSteps&&) noexcept;

    double lambda() const { return m_lambda; }
    std::size_t vertices() const { return m_weld.size(); }  ///< of the mesh (texels of an image)
    std::size_t points() const { return m_points; }         ///< distinct positions (u's rows)
    unsigned channels() const { return m_channels; }        ///< floats per point: 3 for a mesh

    /// u = (I + lambda L) x, x the positions of every vertex (channels() per vertex; the copies
    /// of a point must agree: the first one's is taken). points() rows of channels().
    std::vector<float> to_differential(const std::vector<float>& x) const;
    /// x = (I + lambda L)^-1 u, for every vertex of the mesh (copies get their point's).
    std::vector<float> from_differential(const std::vector<float>& u) const;
    /// The gradient with respect to u of a loss whose gradient with respect to x is g
    /// (channels() per vertex): (I + lambda L)^-1 applied to the sum of each point's copies.
    std::vector<float> gradient(const std::vector<float>& g) const;

    /// The matrix I + lambda L of the points, dense, row-major (tests: a reference).
    std::vector<double> dense_matrix() const;

private:
    struct Solver;
    /// Each vertex's point in `weld` (points: its largest entry + 1), `channels` floats each.
    LargeSteps(double lambda, std::vector<unsigned> weld, unsigned channels);
    /// Factorizes I + lambda L of the points joined by `edges` (each pair once, p < q).
    void factorize(const std::vector<std::pair<unsigned, unsigned>>& edges);
    double m_lambda;
    unsigned m_channels = 3;
    std::vector<unsigned> m_weld; ///< each vertex's point
    std::size_t m_points = 0;
    std::unique_ptr<Solver> m_solver;
};

} // namespace tandem
