// The scene's bitmap textures, loaded once: the parameter registry takes their texels as the
// start values of texture parameters, and the flattening step uploads the rest.
#pragma once

#include <vector>

#include "core/scene/scene.h"

namespace tandem {

/// One loaded bitmap: linear RGB, row-major from the top-left texel.
struct Bitmap {
    int width = 0, height = 0;
    std::vector<float> rgb; ///< 3 floats per texel
};

/// Loads every bitmap of `desc` (sRGB decoded unless `raw`); one entry per SceneDesc::textures,
/// empty for procedural textures. Throws Error "FILE:LINE: texture 'ID': ..." for an unreadable
/// file or non-finite texels.
std::vector<Bitmap> load_bitmaps(const SceneDesc& desc);

} // namespace tandem
