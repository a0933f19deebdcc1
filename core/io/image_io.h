// Image input and output through OpenImageIO.
#pragma once

#include <string>
#include <vector>

namespace tandem {

/// Writes linear RGB (row-major from the top-left) to `path`. The format follows the extension:
/// .exr keeps 32-bit float linear values; .png (and other 8-bit formats) get sRGB-encoded values
/// clamped to [0, 1]. The file is written beside the target and renamed over it, so an existing
/// file is never left half-written. Throws Error naming the file on failure.
void write_image(const std::string& path, int width, int height, const std::vector<float>& rgb);

/// Checks, before any work, that write_image(path, ...) can succeed: an image format for the
/// extension and an existing folder. Throws Error naming `path` otherwise.
void check_image_output(const std::string& path);

/// check_image_output() for values that are signed and unbounded (a gradient): an 8-bit format
/// would clamp them to [0, 1], so only .exr is accepted.
void check_signed_image_output(const std::string& path);

/// The most texels read_image() accepts (8192 x 8192): what a header claims is checked before
/// anything is allocated.
constexpr long long k_max_image_texels = 8192LL * 8192LL;

/// Reads an image as RGB floats (a grey image is replicated; alpha is dropped). With
/// `decode_srgb`, integer-format files are decoded from sRGB to linear; float formats are taken as
/// linear. Throws Error naming the file on failure, on an image without pixels or over
/// k_max_image_texels, and on NaN or Inf texels (naming the texel).
std::vector<float> read_image(const std::string& path, int* width, int* height,
                              bool decode_srgb = true);

/// read_image() of an image that must match a film of width x height (a reference or target:
/// finite, linear). Throws Error "PATH: the <what> is WxH, the scene renders wxh" otherwise.
std::vector<float> read_film_image(const std::string& path, const char* what, unsigned width,
                                   unsigned height);

/// An image as its file stores it (the first subimage), for bit-exact comparison: each channel's
/// values in the file's own format, nothing converted (Tandem's EXR files: 32-bit float words;
/// a half EXR: 16-bit words; 8-bit formats: bytes), NaN and Inf included.
struct StoredImage {
    int x = 0, y = 0;                  ///< the data window's origin
    int width = 0, height = 0;         ///< pixels
    std::vector<std::string> channels; ///< names, in the reader's order
    std::vector<std::string> formats;  ///< each channel's format: "float", "half", "uint8", ...
    std::vector<int> bytes;            ///< each channel's size in bytes
    std::vector<unsigned char> data;   ///< pixels row-major from the top left, channels packed
};

/// The image at `path` as stored. Throws Error naming the file when it cannot be read (the header
/// checks of read_image(), which this shares); non-finite values are kept, not refused.
StoredImage read_stored_image(const std::string& path);

} // namespace tandem
