// Fuzzes image reading as Tandem does it (read_image through OpenImageIO: textures, environment
// maps, targets and references), then what an environment map builds from it (build_envmap).
// The first byte picks the extension (byte % 5: .png .exr .pfm .hdr .jpg) and, in bit 7,
// whether integer formats are decoded from sRGB; the rest is the file.
#include <cstddef>
#include <cstdint>

#include <glm/mat4x4.hpp>

#include "core/io/image_io.h"
#include "core/scene/render_scene.h"
#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    tandem::fuzz::single_threaded_images();
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size < 1) return 0;
    const char* const names[] = {"image.png", "image.exr", "image.pfm", "image.hdr", "image.jpg"};
    const std::string path = tandem::fuzz::write_input(data + 1, size - 1, names[(data[0] & 0x7f) % 5]);
    const bool decode_srgb = (data[0] & 0x80) != 0;
    tandem::fuzz::expect_load_or_error([&] {
        int w = 0, h = 0;
        const std::vector<float> rgb = tandem::read_image(path, &w, &h, decode_srgb);
        tandem::RenderScene scene;
        tandem::build_envmap(rgb, w, h, glm::mat4(1.0f), scene);
    });
    return 0;
}
