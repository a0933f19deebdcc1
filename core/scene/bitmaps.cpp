// Bitmap loading for textures.
#include "core/scene/bitmaps.h"

#include "core/io/image_io.h"
#include "runtime/error.h"

namespace tandem {

std::vector<Bitmap> load_bitmaps(const SceneDesc& desc) {
    std::vector<Bitmap> out(desc.textures.size());
    for (std::size_t i = 0; i < desc.textures.size(); ++i) {
        const Texture& t = desc.textures[i];
        if (t.kind != Texture::Kind::bitmap) continue;
        try {
            out[i].rgb = read_image(t.filename, &out[i].width, &out[i].height, t.srgb);
        } catch (const Error& e) {
            // a texture nested in its bsdf has no id: the line names it
            const std::string name = t.id.empty() ? "<texture>" : "texture '" + t.id + "'";
            throw Error(desc.path + ":" + std::to_string(t.line) + ": " + name + ": " + e.what());
        }
    }
    return out;
}

} // namespace tandem
