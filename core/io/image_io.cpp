// Image output through OpenImageIO, written atomically.
#include "core/io/image_io.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <map>

#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include "core/io/atomic_file.h"
#include "runtime/error.h"
#include "runtime/fault.h"
#include "runtime/stderr_redirect.h"

namespace tandem {

namespace fs = std::filesystem;

namespace {

float linear_to_srgb(float c) {
    c = std::clamp(c, 0.0f, 1.0f);
    return c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

std::string extension(const std::string& path) {
    std::string ext = fs::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return std::tolower(c); });
    return ext;
}

[[noreturn]] void too_large(const std::string& path, std::int64_t w, std::int64_t h) {
    throw Error(path + ": the image is " + std::to_string(w) + "x" + std::to_string(h) +
                ", more than the " + std::to_string(k_max_image_texels) +
                " texels (8192x8192) Tandem reads");
}

/// The value size OpenEXR (3.1) reads for an attribute type of fixed size, whatever the
/// attribute's size field says; 0 for other types.
int exr_fixed_size(const std::string& type) {
    static const std::map<std::string, int> sizes = {{"box2i", 16},
                                                     {"box2f", 16},
                                                     {"chromaticities", 32},
                                                     {"compression", 1},
                                                     {"deepImageState", 1},
                                                     {"double", 8},
                                                     {"envmap", 1},
                                                     {"float", 4},
                                                     {"int", 4},
                                                     {"keycode", 28},
                                                     {"lineOrder", 1},
                                                     {"m33f", 36},
                                                     {"m33d", 72},
                                                     {"m44f", 64},
                                                     {"m44d", 128},
                                                     {"rational", 8},
                                                     {"tiledesc", 9},
                                                     {"timecode", 8},
                                                     {"v2i", 8},
                                                     {"v2f", 8},
                                                     {"v2d", 16},
                                                     {"v3i", 12},
                                                     {"v3f", 12},
                                                     {"v3d", 24}};
    const auto it = sizes.find(type);
    return it == sizes.end() ? 0 : it->second;
}

/// OpenEXR allocates what a header's fields claim before it reads them: a string attribute's
/// size (a 341-byte file asked for 1.9 GB, found by fuzz_image), a preview's width and height, a
/// string vector's lengths. And some types' values are read by their layout, not by the size
/// field (a channel list until its empty name, a box2i as 16 bytes), so a size field that
/// disagrees sets OpenEXR reading the rest of the header from other offsets (an 822-byte file
/// whose channel list claimed 55 bytes and held more: OpenEXR then read a string of 1.9 GB).
/// So, before OpenImageIO opens an EXR file, every attribute of its header(s) must fit in the
/// file and hold exactly what its type reads, and the data window must be within the texel
/// limit. A valid file passes whatever it holds; this refuses only headers OpenEXR would misread.
void check_exr_header(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    char magic[4] = {};
    std::uint32_t version = 0;
    in.read(magic, 4).read(reinterpret_cast<char*>(&version), 4);
    if (!in || std::memcmp(magic, "\x76\x2f\x31\x01", 4) != 0) return; // not EXR: OIIO decides
    std::error_code ec;
    const auto size = static_cast<std::int64_t>(fs::file_size(path, ec));
    const bool multipart = (version & 0x1000) != 0;
    auto fail = [&](const std::string& what) {
        throw Error(path + ": cannot read image: EXR header: " + what);
    };
    auto read_string = [&]() { // a name or a type: NUL-terminated, at most 255 characters
        std::string s;
        for (char c; in.get(c) && c != '\0';)
            if (s.size() == 255) fail("a name longer than 255 characters");
            else s += c;
        if (!in) fail("the file ends inside the header");
        return s;
    };
    auto read_i32 = [&]() {
        std::int32_t v = 0;
        in.read(reinterpret_cast<char*>(&v), 4);
        if (!in) fail("the file ends inside the header");
        return v;
    };
    for (int part = 0;; ++part) {
        std::string name = read_string();
        if (name.empty()) { // the end of this header, or of the list of headers (multi-part)
            if (part == 0 || !multipart) fail("no attributes");
            break;
        }
        for (; !name.empty(); name = read_string()) {
            const std::string type = read_string();
            const std::int32_t bytes = read_i32();
            const std::int64_t start = static_cast<std::int64_t>(in.tellg());
            const std::int64_t left = size - start;
            if (bytes < 0 || bytes > left)
                fail("attribute '" + name + "' claims " + std::to_string(bytes) +
                     " bytes, the file has " + std::to_string(std::max<std::int64_t>(left, 0)) +
                     " left");
            auto holds = [&](std::int64_t reads) { // what the type reads against the size field
                if (reads != bytes)
                    fail("attribute '" + name + "' of type '" + type + "' claims " +
                         std::to_string(bytes) + " bytes and holds " + std::to_string(reads));
            };
            if (const int fixed = exr_fixed_size(type)) {
                holds(fixed);
            } else if (type == "chlist") { // names until an empty one, 16 bytes after each
                for (std::string channel = read_string(); !channel.empty();
                     channel = read_string()) {
                    in.seekg(16, std::ios::cur);
                    if (static_cast<std::int64_t>(in.tellg()) - start > bytes) break;
                }
                holds(static_cast<std::int64_t>(in.tellg()) - start);
            } else if (type == "preview") { // width, height, then 4 bytes per pixel
                const std::int64_t w = std::uint32_t(read_i32()), h = std::uint32_t(read_i32());
                holds(8 + 4 * w * h);
            } else if (type == "stringvector") { // (length, characters) until the size is used
                for (std::int64_t used = 0; used < bytes;) {
                    const std::int32_t length = read_i32();
                    used += 4;
                    if (length < 0 || used + length > bytes)
                        fail("attribute '" + name + "' holds a string of " +
                             std::to_string(length) + " bytes past its end");
                    in.seekg(length, std::ios::cur);
                    used += length;
                }
            }
            if (name == "dataWindow" && type == "box2i") {
                in.seekg(start);
                std::int32_t box[4] = {};
                in.read(reinterpret_cast<char*>(box), 16);
                const std::int64_t w = std::int64_t(box[2]) - box[0] + 1;
                const std::int64_t h = std::int64_t(box[3]) - box[1] + 1;
                if (w <= 0 || h <= 0) fail("an empty data window");
                if (w * h > k_max_image_texels) too_large(path, w, h);
            }
            in.seekg(start + bytes);
        }
        if (!multipart) break;
    }
}

/// Calls f(), a read of OpenImageIO's, with stderr discarded. Its PNG reader (2.4, Debian 12)
/// returns from libpng's error callback, so libpng prints its own "libpng error: ..." line before
/// OpenImageIO reports the same error through geterror(), which the Error thrown carries: the
/// user gets that one line only. Sanitizer builds (the fuzzers') keep stderr, where a report of
/// a fault inside a reader must go.
template <class F> auto quietly(F&& f) {
#ifdef TANDEM_SANITIZED
    return f();
#else
    const StderrRedirect quiet(StderrRedirect::discard);
    return f();
#endif
}

} // namespace

void check_image_output(const std::string& path) {
    check_output_file(path);
    if (!OIIO::ImageOutput::create(path))
        throw Error(path + ": no image format for the extension '" + extension(path) +
                    "' (.exr for linear float, .png for 8-bit sRGB)");
}

void check_signed_image_output(const std::string& path) {
    check_image_output(path);
    const std::string ext = extension(path);
    if (ext != ".exr")
        throw Error(path + ": a gradient needs a float format that keeps its sign (.exr), not '" +
                    ext + "'");
}

void write_image(const std::string& path, int width, int height, const std::vector<float>& rgb) {
    if (rgb.size() != std::size_t(width) * height * 3)
        throw Error(path + ": image data does not match " + std::to_string(width) + "x" +
                    std::to_string(height));
    const std::string ext = extension(path);
    const bool hdr = ext == ".exr" || ext == ".hdr" || ext == ".pfm";
    // Temporary name in the same folder, with the same extension so OIIO picks the format.
    const fs::path target(path);
    const fs::path tmp = temporary_for(path, ext);
    auto out = OIIO::ImageOutput::create(tmp.string());
    if (!out)
        throw Error(path + ": no image format for the extension '" + ext +
                    "' (.exr for linear float, .png for 8-bit sRGB)");
    OIIO::ImageSpec spec(width, height, 3, hdr ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8);
    // No time of writing in the header (OpenImageIO's EXR writer adds one unless DateTime is
    // given, and writes none for an empty one): the same inputs give the same file, byte for byte.
    spec.attribute("DateTime", "");
    bool ok = out->open(tmp.string(), spec);
    if (ok) {
        fault::kill_point("write-middle"); // tests: a kill with the header written, no pixels
        if (hdr) {
            ok = out->write_image(OIIO::TypeDesc::FLOAT, rgb.data());
        } else {
            std::vector<unsigned char> bytes(rgb.size());
            for (std::size_t i = 0; i < rgb.size(); ++i)
                bytes[i] = static_cast<unsigned char>(std::lround(255.0f * linear_to_srgb(rgb[i])));
            ok = out->write_image(OIIO::TypeDesc::UINT8, bytes.data());
        }
        ok = out->close() && ok;
    }
    std::string why = out->geterror();
    if (ok && fault::fail_this_write()) { // tests: a disk that is full
        ok = false;
        why = std::string(std::strerror(ENOSPC)) + "; injected: TANDEM_FAIL_WRITE";
    }
    if (ok) { // on the disk before the rename, as write_file_atomic
        const int fd = ::open(tmp.c_str(), O_RDONLY | O_CLOEXEC);
        ok = fd >= 0 && ::fsync(fd) == 0;
        if (!ok) why = std::strerror(errno);
        if (fd >= 0) ::close(fd);
    }
    if (ok) fault::kill_point("write-complete"); // tests: a kill between the flush and the rename
    std::error_code ec;
    if (!ok) {
        fs::remove(tmp, ec);
        // OIIO's message names the temporary: name the user's file instead
        for (std::size_t at; (at = why.find(tmp.string())) != std::string::npos;)
            why.replace(at, tmp.string().size(), path);
        throw Error(path + ": cannot write image: " + (why.empty() ? "unknown error" : one_line(why)));
    }
    fs::rename(tmp, target, ec);
    if (ec) {
        const std::string reason = ec.message(); // before remove() overwrites ec
        fs::remove(tmp, ec);
        throw Error(path + ": cannot move the finished image into place: " + reason);
    }
}

namespace {

/// An image's first channels as floats, as OpenImageIO converts them (integer formats to [0, 1]),
/// interleaved row-major from the top left: the colour channels (1, grey, or 3) and, when asked
/// for and the file has one after them, its alpha channel. Nothing is decoded or checked for
/// finiteness here; the header checks are made before anything is allocated.
struct Channels {
    int width = 0, height = 0;
    int colour = 0;       ///< 1 (grey: a file of fewer than 3 channels) or 3
    int count = 0;        ///< channels per pixel in `data`: `colour`, or `colour` + 1 (alpha)
    bool alpha = false;   ///< the last of `count` is the file's alpha channel
    bool integer = false; ///< an 8- or 16-bit integer format (sRGB-encoded by convention)
    std::vector<float> data;
};

/// Reads `path` into Channels. With `as_stored`, OpenImageIO is told (oiio:UnassociatedAlpha)
/// not to premultiply the colours a file stores unassociated (PNG): the colour channels are what
/// the file holds, never multiplied or divided by alpha. Without it, they are what OpenImageIO
/// delivers by default (PNG's premultiplied). With `with_alpha`, the alpha channel
/// (spec.alpha_channel, when it is not one of the colour channels) is read too.
Channels read_channels(const std::string& path, bool as_stored, bool with_alpha) {
    check_exr_header(path);
    OIIO::ImageSpec config;
    if (as_stored) config.attribute("oiio:UnassociatedAlpha", 1);
    auto in = quietly([&] { return OIIO::ImageInput::open(path, &config); });
    if (!in) throw Error(path + ": cannot read image (" + one_line(OIIO::geterror()) + ")");
    const OIIO::ImageSpec& spec = in->spec();
    const int w = spec.width, h = spec.height, c = spec.nchannels;
    // The header's size, checked before anything is allocated: a file of a few bytes can claim
    // any size.
    if (w <= 0 || h <= 0 || c <= 0)
        throw Error(path + ": cannot read image: it has no pixels (" + std::to_string(w) + "x" +
                    std::to_string(h) + ", " + std::to_string(c) + " channels)");
    if (std::int64_t(w) * h > k_max_image_texels) too_large(path, w, h);
    Channels image;
    image.width = w;
    image.height = h;
    // grey (+ alpha) images: the first channel; RGB(A): the first three
    image.colour = c < 3 ? 1 : 3;
    const int a = spec.alpha_channel;
    image.alpha = with_alpha && a >= image.colour && a < c;
    image.count = image.colour + (image.alpha ? 1 : 0);
    image.integer = spec.format == OIIO::TypeDesc::UINT8 || spec.format == OIIO::TypeDesc::UINT16;
    image.data.resize(std::size_t(w) * h * image.count);
    const std::size_t stride = image.count * sizeof(float);
    // Only the channels used are read, straight into their places: one read when the alpha
    // channel follows the colour ones (RGBA, grey + alpha), else a second one for it.
    const bool next = image.alpha && a == image.colour;
    const bool ok = quietly([&] {
        return in->read_image(0, 0, 0, image.count - (image.alpha && !next), OIIO::TypeDesc::FLOAT,
                              image.data.data(), stride) &&
               (!image.alpha || next ||
                in->read_image(0, 0, a, a + 1, OIIO::TypeDesc::FLOAT,
                               image.data.data() + image.colour, stride));
    });
    if (!ok) throw Error(path + ": cannot read image: " + one_line(in->geterror()));
    return image;
}

[[noreturn]] void not_finite(const std::string& path, std::size_t pixel, int width) {
    throw Error(path + ": the texel at column " + std::to_string(pixel % std::size_t(width)) +
                ", row " + std::to_string(pixel / std::size_t(width)) +
                " (from the top left, from 0) is not finite");
}

/// `image`'s colour as linear RGB (grey replicated), integer formats decoded from sRGB when
/// `decode_srgb`. Throws Error naming the first non-finite texel. When `image` holds RGB alone,
/// its data is converted in place and taken (no second copy of a large texture); its other
/// fields stay.
std::vector<float> linear_rgb(const std::string& path, Channels& image, bool decode_srgb) {
    const std::size_t n = std::size_t(image.width) * image.height;
    const bool srgb = decode_srgb && image.integer;
    const bool in_place = image.count == 3;
    std::vector<float> rgb = in_place ? std::move(image.data) : std::vector<float>(n * 3);
    const float* data = in_place ? rgb.data() : image.data.data();
    for (std::size_t i = 0; i < n; ++i) {
        const float* in = &data[i * image.count];
        float* texel = &rgb[i * 3];
        for (int k = 0; k < 3; ++k) {
            float v = in[image.colour == 1 ? 0 : k];
            if (!std::isfinite(v)) not_finite(path, i, image.width);
            if (srgb) v = v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
            texel[k] = v;
        }
    }
    return rgb;
}

/// Throws "PATH: the <what> is WxH, <film> renders wxh" unless `image` is width x height.
void check_film_size(const std::string& path, const char* what, const Channels& image,
                     unsigned width, unsigned height, const std::string& film) {
    if (unsigned(image.width) != width || unsigned(image.height) != height)
        throw Error(path + ": the " + what + " is " + std::to_string(image.width) + "x" +
                    std::to_string(image.height) + ", " + film + " renders " +
                    std::to_string(width) + "x" + std::to_string(height));
}

/// Channel `k` of every pixel of `image` as a mask: finite and in [0, 1], taken as it is (no sRGB
/// decoding). Throws Error naming the file and the first pixel otherwise, and when every pixel
/// is 0 (nothing would count).
std::vector<float> mask_channel(const std::string& path, const Channels& image, int k,
                                const char* what) {
    const std::size_t n = std::size_t(image.width) * image.height;
    std::vector<float> mask(n);
    bool any = false;
    for (std::size_t i = 0; i < n; ++i) {
        const float v = image.data[i * image.count + k];
        if (!std::isfinite(v)) not_finite(path, i, image.width);
        if (v < 0.0f || v > 1.0f) {
            char value[32];
            std::snprintf(value, sizeof(value), "%g", double(v));
            throw Error(path + ": the " + what + " at column " +
                        std::to_string(i % std::size_t(image.width)) + ", row " +
                        std::to_string(i / std::size_t(image.width)) +
                        " (from the top left, from 0) is " + value + ", outside [0, 1]");
        }
        any = any || v > 0.0f;
        mask[i] = v;
    }
    if (!any)
        throw Error(path + ": the " + what + " is 0 at every pixel: no pixel of the target counts");
    return mask;
}

} // namespace

std::vector<float> read_image(const std::string& path, int* width, int* height, bool decode_srgb) {
    Channels image = read_channels(path, false, false);
    std::vector<float> rgb = linear_rgb(path, image, decode_srgb);
    *width = image.width;
    *height = image.height;
    return rgb;
}

TargetImage read_target_image(const std::string& path, const std::string& mask_path, unsigned width,
                              unsigned height, const std::string& film) {
    Channels image = read_channels(path, true, mask_path.empty());
    check_film_size(path, "target", image, width, height, film);
    TargetImage target;
    target.rgb = linear_rgb(path, image, true); // keeps image.data when it holds alpha
    if (!mask_path.empty()) {
        const Channels mask = read_channels(mask_path, true, false);
        check_film_size(mask_path, "mask", mask, width, height, film);
        target.mask = mask_channel(mask_path, mask, 0, "mask");
    } else if (image.alpha) {
        target.mask = mask_channel(path, image, image.colour, "alpha");
    }
    return target;
}

StoredImage read_stored_image(const std::string& path) {
    check_exr_header(path);
    auto in = quietly([&] { return OIIO::ImageInput::open(path); });
    if (!in) throw Error(path + ": cannot read image (" + one_line(OIIO::geterror()) + ")");
    const OIIO::ImageSpec& spec = in->spec();
    if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 || spec.depth != 1)
        throw Error(path + ": cannot read image: it has no pixels (" + std::to_string(spec.width) +
                    "x" + std::to_string(spec.height) + ", " + std::to_string(spec.nchannels) +
                    " channels)");
    if (std::int64_t(spec.width) * spec.height > k_max_image_texels)
        too_large(path, spec.width, spec.height);
    StoredImage image;
    image.x = spec.x;
    image.y = spec.y;
    image.width = spec.width;
    image.height = spec.height;
    for (int c = 0; c < spec.nchannels; ++c) {
        const OIIO::TypeDesc format = spec.channelformat(c);
        image.channels.push_back(spec.channel_name(c));
        image.formats.push_back(format.c_str());
        image.bytes.push_back(int(format.size()));
    }
    // TypeDesc::UNKNOWN: each channel in its own format, as the file holds it
    image.data.resize(spec.image_bytes(true));
    if (!quietly([&] {
            return in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::UNKNOWN,
                                  image.data.data());
        }))
        throw Error(path + ": cannot read image: " + one_line(in->geterror()));
    return image;
}

std::vector<float> read_film_image(const std::string& path, const char* what, unsigned width,
                                   unsigned height) {
    Channels image = read_channels(path, false, false);
    check_film_size(path, what, image, width, height, "the scene");
    return linear_rgb(path, image, true);
}

} // namespace tandem
