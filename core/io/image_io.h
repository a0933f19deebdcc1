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

/// A target photograph of one sensor: linear RGB (3 floats a pixel, row-major from the top left)
/// and its mask (one float a pixel in [0, 1]; empty: every pixel counts fully).
struct TargetImage {
    std::vector<float> rgb;
    /// Each pixel's weight in the loss: 0 excludes it, 1 counts it fully, a value between weighs
    /// it by that fraction (a soft matte's edges); at least one pixel is above 0.
    std::vector<float> mask;
};

/// Reads the target photograph of a film of width x height from `path`: EXR (and other float
/// formats) as linear, PNG, JPEG and other 8- or 16-bit formats decoded from sRGB. The mask is
/// `mask_path`'s first channel (a grey image), if a mask is given, else `path`'s alpha channel if
/// it has one, else none (an empty mask). A mask is taken as stored, never sRGB-decoded (8 bits:
/// code / 255). The RGB is the colour the file stores, never multiplied or divided by alpha: a
/// PNG's colour is unassociated by its specification and OpenImageIO is told not to premultiply
/// it; an EXR's is associated by convention and kept as stored (the two agree where alpha is 0
/// or 1). `film` names the film in messages ("the sensor 'cam0'"). Throws Error, one line
/// "PATH: ..." naming the file at fault, on: a missing or unreadable file (or the errors of
/// read_image()), a size other than the film's ("PATH: the target is WxH, <film> renders wxh",
/// likewise "the mask is"), a non-finite texel (naming it), a mask value that is not finite or
/// outside [0, 1] (naming the pixel), and a mask that is 0 at every pixel.
TargetImage read_target_image(const std::string& path, const std::string& mask_path, unsigned width,
                              unsigned height, const std::string& film);

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
