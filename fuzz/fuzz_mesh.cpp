// Fuzzes mesh loading as Tandem does it (load_mesh: Assimp, then validation), then what follows a
// load: the bounds, and the BVH in every layout (Embree's build, the leaf repacking, flattening),
// each checked by check_bvh. The first byte picks the file's extension, which picks Assimp's
// importer: even .obj, odd .ply; the rest is the file.
#include <cstddef>
#include <cstdint>

#include "core/scene/mesh.h"
#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size < 1) return 0;
    const char* name = data[0] % 2 == 0 ? "mesh.obj" : "mesh.ply";
    const std::string path = tandem::fuzz::write_input(data + 1, size - 1, name);
    tandem::fuzz::expect_load_or_error([&] {
        const tandem::TriangleMesh mesh = tandem::load_mesh(path);
        (void)mesh.bounds();
        for (int width : {2, 4, 8}) {
            tandem::fuzz::build_and_check_bvh(mesh, width, tandem::LeafFormat::records);
            if (width != 2)
                tandem::fuzz::build_and_check_bvh(mesh, width, tandem::LeafFormat::tri4);
        }
    });
    return 0;
}
