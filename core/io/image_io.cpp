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

std::vector<float> read_image(const std::string& path, int* width, int* height, bool decode_srgb) {
    check_exr_header(path);
    auto in = quietly([&] { return OIIO::ImageInput::open(path); });
    if (!in) throw Error(path + ": cannot read image (" + one_line(OIIO::geterror()) + ")");
    const OIIO::ImageSpec& spec = in->spec();
    const int w = spec.width, h = spec.height, c = spec.nchannels;
    // The header's size, checked before anything is allocated: a file of a few bytes can claim
    // any size.
    if (w <= 0 || h <= 0 || c <= 0)
        throw Error(path + ": cannot read image: it has no pixels (" + std::to_string(w) + "x" +
                    std::to_string(h) + ", " + std::to_string(c) + " channels)");
    if (std::int64_t(w) * h > k_max_image_texels) too_large(path, w, h);
    // grey (+ alpha) images: grey in every channel; RGB(A): the first three. Only the channels
    // used are read, straight into their places in `rgb`.
    const int used = c < 3 ? 1 : 3;
    std::vector<float> rgb(std::size_t(w) * h * 3);
    if (!quietly([&] {
            return in->read_image(0, 0, 0, used, OIIO::TypeDesc::FLOAT, rgb.data(),
                                  3 * sizeof(float));
        }))
        throw Error(path + ": cannot read image: " + one_line(in->geterror()));
    const bool integer =
        spec.format == OIIO::TypeDesc::UINT8 || spec.format == OIIO::TypeDesc::UINT16;
    const bool srgb = decode_srgb && integer;
    for (std::size_t i = 0; i < std::size_t(w) * h; ++i) {
        float* texel = &rgb[i * 3];
        if (used == 1) texel[1] = texel[2] = texel[0];
        for (int k = 0; k < 3; ++k) {
            float v = texel[k];
            if (!std::isfinite(v))
                throw Error(path + ": the texel at column " + std::to_string(i % std::size_t(w)) +
                            ", row " + std::to_string(i / std::size_t(w)) +
                            " (from the top left, from 0) is not finite");
            if (srgb) v = v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
            texel[k] = v;
        }
    }
    *width = w;
    *height = h;
    return rgb;
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
    int w = 0, h = 0;
    std::vector<float> rgb = read_image(path, &w, &h, true);
    if (unsigned(w) != width || unsigned(h) != height)
        throw Error(path + ": the " + what + " is " + std::to_string(w) + "x" + std::to_string(h) +
                    ", the scene renders " + std::to_string(width) + "x" + std::to_string(height));
    return rgb;
}

} // namespace tandem
