// Fuzzes the Mitsuba XML scene loader as `tandem render` uses it: load_scene on the input (a file
// in a folder with textures/ and meshes/, so relative file references of the seeds resolve),
// then build_render_scene on what loads (meshes, bitmaps, environment maps, lights, tables), then
// the scene's BVH in the layouts a device may take (two- and eight-wide records, and blocks of four
// where every primitive is a triangle), each checked by check_bvh.
#include <cstddef>
#include <cstdint>

#include "core/scene/render_scene.h"
#include "core/scene/scene.h"
#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    tandem::fuzz::single_threaded_images();
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = tandem::fuzz::write_input(data, size, "scene.xml");
    tandem::fuzz::expect_load_or_error([&] {
        const tandem::SceneDesc desc = tandem::load_scene(path);
        const tandem::RenderScene scene = tandem::build_render_scene(desc);
        const tandem::TriangleMesh& mesh = scene.mesh;
        tandem::fuzz::build_and_check_bvh(mesh, 2, tandem::LeafFormat::records);
        tandem::fuzz::build_and_check_bvh(mesh, 8, tandem::LeafFormat::records);
        if (mesh.primitive_count() == mesh.triangle_count()) // blocks hold triangles only
            tandem::fuzz::build_and_check_bvh(mesh, 8, tandem::LeafFormat::tri4);
    });
    return 0;
}
