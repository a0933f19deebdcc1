// Mesh loading (OBJ, ASCII PLY, binary PLY) and rejection of bad input.
#include <doctest/doctest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

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

    TEST_CASE("binary PLY whose data begins with the byte 0x0A loads its own values") {
        // Assimp 5.2 skips such a byte after an end_header line ended by a bare line feed, and
        // read every value one byte late (ply_for_assimp): a face came out empty, and Assimp's
        // triangulation aborted the process. Each first byte, after either line ending.
        const std::string header =
            "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
            "property float y\nproperty float z\nelement face 1\n"
            "property list uchar int vertex_indices\nend_header";
        const std::filesystem::path dir =
            std::filesystem::temp_directory_path() / ("tandem-mesh-test-" + std::to_string(getpid()));
        std::filesystem::create_directories(dir);
        for (const unsigned char first : {0x0A, 0x0D, 0x20, 0x41})
            for (const char* eol : {"\n", "\r\n"}) {
                const unsigned char x0_bytes[4] = {first, 0x0A, 0x80, 0x3F}; // near 1.0, little-endian
                float x0;
                std::memcpy(&x0, x0_bytes, 4);
                const float v[9] = {x0, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f};
                const unsigned char count = 3;
                const int idx[3] = {0, 1, 2};
                const std::string path = (dir / "first.ply").string();
                {
                    std::ofstream out(path, std::ios::binary);
                    out << header << eol;
                    out.write(reinterpret_cast<const char*>(v), sizeof v);
                    out.write(reinterpret_cast<const char*>(&count), 1);
                    out.write(reinterpret_cast<const char*>(idx), sizeof idx);
                }
                INFO("first byte " << int(first) << std::string(eol[0] == '\r' ? ", CRLF" : ", LF"));
                const TriangleMesh m = load_mesh(path);
                REQUIRE(m.triangle_count() == 1);
                CHECK(corners(m) ==
                      std::vector<glm::vec3>{{x0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
            }
        std::filesystem::remove_all(dir);
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
