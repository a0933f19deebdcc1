// Shading normals (core/scene/vertex_normals.h): the angle weighting, the derivatives of derived
// normals against central differences, and what a scene's meshes are shaded with.
#include <doctest/doctest.h>

#include <cmath>
#include <string>

#include <glm/geometric.hpp>

#include "core/scene/render_scene.h"
#include "core/scene/scene.h"
#include "core/scene/shape_mesh.h"
#include "core/scene/vertex_normals.h"

using namespace tandem;

namespace {

const std::string k_scenes = std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/";

/// The render scene of tests/scenes/smooth-sphere.xml with `defines`.
RenderScene smooth_sphere(const std::vector<std::pair<std::string, std::string>>& defines) {
    return build_render_scene(load_scene(k_scenes + "smooth-sphere.xml", defines));
}

} // namespace

TEST_SUITE("vertex normals") {
    // The weighting by interior angles does not depend on how a face is cut into triangles
    // (Thuermer and Wuethrich's point): each face of a cube gives each of its corners pi / 2,
    // whether the corner is on the diagonal of the cut (two triangles, pi / 4 each) or not. So
    // every corner of the triangulated cube gets (+-1, +-1, +-1) / sqrt(3); weights by area, or
    // none, give the diagonal's corners more of the faces they cut. The cube's faces are split
    // (a vertex per face corner): vertices at one position share the normal.
    TEST_CASE("a cube's corners get the diagonal, whatever the triangulation") {
        Shape cube;
        cube.type = ShapeType::cube;
        const TriangleMesh m = shape_mesh(cube, "cube");
        const std::vector<glm::dvec3> n = derived_normals(m.positions, m.triangles);
        REQUIRE(n.size() == m.positions.size());
        for (std::size_t i = 0; i < n.size(); ++i) {
            const glm::dvec3 expected = glm::dvec3(glm::sign(m.positions[i])) / std::sqrt(3.0);
            INFO("vertex " << i);
            CHECK(glm::length(n[i] - expected) < 1e-12);
        }
    }

    // dN_k/dP_j against central differences of derived_normals, on a jittered height field
    // (every vertex has a different ring). The steps are taken in float (positions are floats)
    // and each difference divides by the step actually taken, so the remaining error is the
    // truncation, O(h^2) with h = 2^-10: below 1e-5 of the entries, which are O(1) where a
    // vertex's ring is a unit or so across. A wrong sign, a missing angle or normal derivative,
    // or a block given to the wrong vertex is O(1).
    TEST_CASE("the derivatives of derived normals match central differences") {
        std::vector<glm::vec3> p;
        std::vector<glm::uvec3> t;
        const int n = 4;
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const float jitter = 0.13f * std::sin(float(7 * i + 3 * j));
                p.emplace_back(float(i) + jitter, float(j) - 0.5f * jitter,
                               0.4f * std::cos(float(i * j) + 0.5f));
            }
        for (unsigned j = 0; j + 1 < n; ++j)
            for (unsigned i = 0; i + 1 < n; ++i) {
                const unsigned a = j * n + i, b = a + 1, c = a + n + 1, d = a + n;
                t.emplace_back(a, b, c);
                t.emplace_back(a, c, d);
            }
        const NormalJacobian jac = normal_jacobian(p, t);
        REQUIRE(jac.first.size() == p.size() + 1);
        const float h = 1.0f / 1024.0f;
        double worst = 0.0;
        for (unsigned v = 0; v < p.size(); ++v)
            for (int c = 0; c < 3; ++c) {
                std::vector<glm::vec3> up = p, down = p;
                up[v][c] += h;
                down[v][c] -= h;
                const double step = double(up[v][c]) - double(down[v][c]);
                const std::vector<glm::dvec3> nu = derived_normals(up, t), nd = derived_normals(down, t);
                for (unsigned k = 0; k < p.size(); ++k) {
                    const glm::dvec3 fd = (nu[k] - nd[k]) / step;
                    glm::dvec3 analytic(0.0);
                    for (unsigned b = jac.first[k]; b < jac.first[k + 1]; ++b)
                        if (jac.vertex[b] == v) analytic = jac.jacobian[b][c];
                    worst = std::max(worst, glm::length(fd - analytic));
                    INFO("dN_" << k << " / dP_" << v << "." << c);
                    CHECK(glm::length(fd - analytic) < 1e-4);
                }
            }
        MESSAGE("largest difference from central differences: " << worst);
    }

    // A file's own normals are used where it has them (moved by to_world like normals: here the
    // sphere's own, so the rotated positions); a file without gets derived ones, which follow the
    // vertices; face_normals keeps the triangles' own. Rectangles stay flat.
    TEST_CASE("what the meshes of a scene are shaded with") {
        const RenderScene file = smooth_sphere({{"kind", "ply"}, {"mesh", "lowpoly_normals.ply"}});
        const MeshShape& ball = file.mesh_shapes.front();
        CHECK(ball.smooth);
        CHECK_FALSE(ball.normals_derived);
        CHECK_FALSE(file.mesh_shapes.back().smooth); // the rectangle
        for (unsigned i = 0; i < ball.vertex_count; ++i)
            CHECK(glm::length(file.mesh.normals[ball.first_vertex + i] -
                              file.mesh.positions[ball.first_vertex + i]) < 1e-5f);
        const RenderScene derived = smooth_sphere({});
        CHECK(derived.mesh_shapes.front().smooth);
        CHECK(derived.mesh_shapes.front().normals_derived);
        const RenderScene face = smooth_sphere({{"face", "true"}});
        CHECK_FALSE(face.mesh_shapes.front().smooth);
        CHECK(face.mesh.normals.empty());
    }
}
