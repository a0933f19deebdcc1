// Angle-weighted vertex normals and their derivatives with respect to the vertex positions.
#include "core/scene/vertex_normals.h"

#include <cmath>

#include <glm/geometric.hpp>
#include <glm/matrix.hpp>

#include "core/scene/mesh.h"

namespace tandem {

namespace {

/// The matrix of v x (.).
glm::dmat3 cross_matrix(const glm::dvec3& v) {
    // column-major: column c is v x e_c
    return glm::dmat3(glm::dvec3(0.0, v.z, -v.y), glm::dvec3(-v.z, 0.0, v.x),
                      glm::dvec3(v.y, -v.x, 0.0));
}

/// A triangle's contribution to the normal of its corner c: its unit normal times its interior
/// angle there, and (with `jac`) the derivatives of that vector with respect to its three
/// vertices, jac[k] = d / dP_k. False for a triangle of zero area (it adds nothing).
bool corner_term(const glm::dvec3 p[3], int c, glm::dvec3* term, glm::dmat3* jac) {
    const glm::dvec3 e1 = p[1] - p[0], e2 = p[2] - p[0];
    const glm::dvec3 m = glm::cross(e1, e2);
    const double len = glm::length(m);
    if (!(len > 0.0)) return false;
    const glm::dvec3 n = m / len;
    const glm::dvec3 a = p[(c + 1) % 3] - p[c], b = p[(c + 2) % 3] - p[c];
    const double la = glm::length(a), lb = glm::length(b);
    const double angle = std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b));
    *term = n * angle;
    if (!jac) return true;
    // d n = (I - n n^T) dM / |M|, with dM = dP1 x e2 + e1 x dP2 - (dP0 x e2 + e1 x dP0)
    const glm::dmat3 project = (glm::dmat3(1.0) - glm::outerProduct(n, n)) / len;
    glm::dmat3 dn[3];
    dn[1] = project * -cross_matrix(e2);
    dn[2] = project * cross_matrix(e1);
    dn[0] = -(dn[1] + dn[2]);
    // d angle / da = -u_a / |a|, u_a the unit vector across a toward b; likewise for b
    const glm::dvec3 ua = glm::normalize(b - a * (glm::dot(a, b) / (la * la)));
    const glm::dvec3 ub = glm::normalize(a - b * (glm::dot(a, b) / (lb * lb)));
    glm::dvec3 dangle[3];
    dangle[(c + 1) % 3] = -ua / la;
    dangle[(c + 2) % 3] = -ub / lb;
    dangle[c] = -(dangle[(c + 1) % 3] + dangle[(c + 2) % 3]);
    for (int k = 0; k < 3; ++k) jac[k] = glm::outerProduct(n, dangle[k]) + dn[k] * angle;
    return true;
}

/// The triangle's corners as doubles.
void corners(const std::vector<glm::vec3>& positions, const glm::uvec3& t, glm::dvec3 p[3]) {
    for (int k = 0; k < 3; ++k) p[k] = glm::dvec3(positions[t[k]]);
}

} // namespace

std::vector<glm::dvec3> derived_normals(const std::vector<glm::vec3>& positions,
                                        const std::vector<glm::uvec3>& triangles) {
    const std::vector<unsigned> weld = weld_by_position(positions.data(), positions.size());
    std::vector<glm::dvec3> sum(positions.size(), glm::dvec3(0.0));
    for (const glm::uvec3& t : triangles) {
        glm::dvec3 p[3], term;
        corners(positions, t, p);
        for (int c = 0; c < 3; ++c)
            if (corner_term(p, c, &term, nullptr)) sum[weld[t[c]]] += term;
    }
    std::vector<glm::dvec3> out(positions.size());
    for (std::size_t i = 0; i < positions.size(); ++i) {
        const glm::dvec3& a = sum[weld[i]];
        const double len = glm::length(a);
        out[i] = len > 0.0 ? a / len : glm::dvec3(1.0, 0.0, 0.0);
    }
    return out;
}

NormalJacobian normal_jacobian(const std::vector<glm::vec3>& positions,
                               const std::vector<glm::uvec3>& triangles) {
    const std::size_t n = positions.size();
    const std::vector<unsigned> weld = weld_by_position(positions.data(), n);
    // each group's triangle corners, in triangle order
    std::vector<std::vector<std::pair<unsigned, int>>> ring(n);
    for (unsigned f = 0; f < triangles.size(); ++f)
        for (int c = 0; c < 3; ++c) ring[weld[triangles[f][c]]].emplace_back(f, c);
    NormalJacobian out;
    out.first.assign(n + 1, 0u);
    std::vector<glm::dmat3> group_jac;
    std::vector<unsigned> group_vertex;
    std::vector<std::size_t> group_first(n, 0), group_count(n, 0);
    for (std::size_t g = 0; g < n; ++g) {
        if (weld[g] != g) continue;
        // A = sum of the corner terms; N = A / |A|, dN = (I - N N^T) dA / |A|
        glm::dvec3 a(0.0);
        std::vector<unsigned> vertices;
        std::vector<glm::dmat3> da;
        for (const auto& [f, c] : ring[g]) {
            glm::dvec3 p[3], term;
            glm::dmat3 jac[3];
            corners(positions, triangles[f], p);
            if (!corner_term(p, c, &term, jac)) continue;
            a += term;
            for (int k = 0; k < 3; ++k) {
                const unsigned v = triangles[f][k];
                std::size_t b = 0;
                while (b < vertices.size() && vertices[b] != v) ++b;
                if (b == vertices.size()) {
                    vertices.push_back(v);
                    da.emplace_back(0.0);
                }
                da[b] += jac[k];
            }
        }
        const double len = glm::length(a);
        group_first[g] = group_vertex.size();
        if (!(len > 0.0)) continue; // the (1, 0, 0) of derived_normals does not move
        const glm::dvec3 N = a / len;
        const glm::dmat3 project = (glm::dmat3(1.0) - glm::outerProduct(N, N)) / len;
        for (std::size_t b = 0; b < vertices.size(); ++b) {
            group_vertex.push_back(vertices[b]);
            group_jac.push_back(project * da[b]);
        }
        group_count[g] = vertices.size();
    }
    for (std::size_t k = 0; k < n; ++k) {
        const unsigned g = weld[k];
        for (std::size_t b = 0; b < group_count[g]; ++b) {
            out.vertex.push_back(group_vertex[group_first[g] + b]);
            out.jacobian.push_back(group_jac[group_first[g] + b]);
        }
        out.first[k + 1] = static_cast<unsigned>(out.vertex.size());
    }
    return out;
}

} // namespace tandem
