// Image output through OpenImageIO.
#pragma once

#include <string>
#include <vector>

namespace tandem {

/// Writes linear RGB (row-major from the top-left) to `path`. The format follows the extension:
/// .exr keeps 32-bit float linear values; .png (and other 8-bit formats) get sRGB-encoded values
/// clamped to [0, 1]. The file is written beside the target and renamed over it, so an existing
/// file is never left half-written. Throws Error naming the file on failure.
void write_image(const std::string& path, int width, int height, const std::vector<float>& rgb);

/// Reads an image as linear RGB floats (sRGB-encoded 8-bit files are decoded). Throws Error
/// naming the file on failure.
std::vector<float> read_image(const std::string& path, int* width, int* height);

} // namespace tandem
