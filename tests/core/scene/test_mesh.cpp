// Mesh loading (OBJ, ASCII PLY, binary PLY) and rejection of bad input.
#include <doctest/doctest.h>

#include "core/scene/mesh.h"
#include "runtime/error.h"
#include "support.h"

using namespace tandem;
using test::mesh_path;

namespace {

/// Triangle corner positions in order, independent of vertex sharing.
std::vector<glm::vec3> corners(const TriangleMesh& m) {
    std::vector<glm::vec3> out;
    for (const glm::uvec3& t : m.triangles)
        for (int k = 0; k < 3; ++k) out.push_back(m.positions[t[k]]);
    return out;
}

} // namespace

TEST_SUITE("mesh") {
    TEST_CASE("OBJ, ASCII PLY and binary PLY load the same triangles in file order") {
        const TriangleMesh obj = load_mesh(mesh_path("knot_small.obj"));
        const TriangleMesh ply = load_mesh(mesh_path("knot_ascii.ply"));
        CHECK(obj.triangle_count() == 1024);
        CHECK(ply.triangle_count() == 1024);
        CHECK(corners(obj) == corners(ply));
        const TriangleMesh big = load_mesh(mesh_path("knot.ply"));
        CHECK(big.triangle_count() == 131072);
        const Bounds b = big.bounds();
        CHECK(b.lo.x > -1.6f);
        CHECK(b.hi.x < 1.6f);
    }

    TEST_CASE("degenerate and duplicate triangles are kept, so primitive ids match the file") {
        const TriangleMesh m = load_mesh(mesh_path("degenerate.obj"));
        CHECK(m.triangle_count() == 19876);
    }

    TEST_CASE("bad mesh files are errors that name the file and the cause") {
        CHECK_THROWS_WITH_AS(load_mesh(mesh_path("nope.obj")),
                             doctest::Contains("nope.obj: mesh file not found"), Error);
        CHECK_THROWS_WITH_AS(load_mesh(mesh_path("corrupt.ply")),
                             doctest::Contains("corrupt.ply: cannot load mesh"), Error);
        CHECK_THROWS_WITH_AS(load_mesh(mesh_path("empty.obj")), doctest::Contains("empty.obj"),
                             Error);
        CHECK_THROWS_WITH_AS(load_mesh(mesh_path("bad_nan.obj")),
                             doctest::Contains("non-finite coordinate"), Error);
        CHECK_THROWS_WITH_AS(load_mesh(mesh_path("bad_inf.obj")),
                             doctest::Contains("non-finite coordinate"), Error);
    }

    TEST_CASE("validation rejects out-of-range indices and empty meshes") {
        TriangleMesh m;
        m.source = "inline";
        CHECK_THROWS_WITH_AS(validate_mesh(m), doctest::Contains("no triangles"), Error);
        m.positions = {glm::vec3(0), glm::vec3(1, 0, 0), glm::vec3(0, 1, 0)};
        m.triangles = {glm::uvec3(0, 1, 3)};
        CHECK_THROWS_WITH_AS(validate_mesh(m), doctest::Contains("references vertex 3"), Error);
    }
}
