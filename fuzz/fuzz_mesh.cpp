// Fuzzes mesh loading as Tandem does it (load_mesh: Assimp, then validation; then the bounds the
// trace benchmark takes). The first byte picks the file's extension, which picks Assimp's
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
    });
    return 0;
}
