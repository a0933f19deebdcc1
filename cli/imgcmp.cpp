// tandem-imgcmp: whether two images store the same words, bit for bit. What "the same bits" means
// for every image a test or script compares (idiff passes NaN against 0.5, and +0 against -0).
//
//   tandem-imgcmp A B [A2 B2 ...]
//
// (several pairs in one call: loading OpenImageIO's libraries takes most of a call's time)
// The same: the same size and data window, the same channels in the same formats, and every
// stored word equal (Tandem's EXR files hold 32-bit floats: NaN payloads and the sign of zero
// count; a half EXR is compared by its 16-bit words, an 8-bit image by its bytes). Metadata is
// not compared. Exits 0 when every pair is the same (printing nothing); 1 when not, with one line
// for each pair that differs naming its first differing pixel and channel, both words in hex and
// as values, and how many words differ; 2 when a file cannot be read or the command line is wrong
// (one line).
#include <cinttypes>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <sstream>
#include <string>

#include <OpenImageIO/imageio.h>

#include "core/io/image_io.h"
#include "runtime/error.h"

namespace {

using tandem::StoredImage;

/// A stored word as hex digits and as the value its format holds: "0x7fc00001 (nan)".
std::string word(const std::string& format, const unsigned char* p, int bytes) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, p, std::size_t(bytes)); // little-endian host: the low bytes
    char hex[24];
    std::snprintf(hex, sizeof(hex), "0x%0*" PRIx64, 2 * bytes, bits);
    const OIIO::TypeDesc type(format);
    std::ostringstream s;
    if (type.is_floating_point()) {
        double value = 0.0;
        if (!OIIO::convert_pixel_values(type, p, OIIO::TypeDesc::DOUBLE, &value, 1)) return hex;
        s.precision(bytes == 8 ? 17 : 9);
        s << value;
    } else if (type.is_signed() && bytes < 8) { // sign-extended
        const std::uint64_t sign = std::uint64_t(1) << (8 * bytes - 1);
        s << std::int64_t((bits ^ sign) - sign);
    } else {
        s << (type.is_signed() ? std::int64_t(bits) : bits);
    }
    return std::string(hex) + " (" + s.str() + ")";
}

std::string join(const std::vector<std::string>& names) {
    std::string out;
    for (const std::string& n : names)
        out += (out.empty() ? "" : ",") + n;
    return out;
}

/// The first difference between `a` and `b`, as one line; empty when they store the same words.
std::string difference(const StoredImage& a, const StoredImage& b) {
    auto window = [](const StoredImage& i) {
        return std::to_string(i.width) + "x" + std::to_string(i.height) + " at (" +
               std::to_string(i.x) + ", " + std::to_string(i.y) + ")";
    };
    if (window(a) != window(b)) return "the images are " + window(a) + " and " + window(b);
    if (a.channels != b.channels)
        return "the channels are " + join(a.channels) + " and " + join(b.channels);
    if (a.formats != b.formats)
        return "the channel formats are " + join(a.formats) + " and " + join(b.formats);
    int pixel_bytes = 0;
    for (int n : a.bytes)
        pixel_bytes += n;
    const std::size_t pixels = std::size_t(a.width) * std::size_t(a.height);
    const std::size_t words = pixels * a.channels.size();
    std::size_t differing = 0;
    std::string first;
    for (std::size_t i = 0; i < pixels; ++i) {
        const std::size_t base = i * std::size_t(pixel_bytes);
        std::size_t at = base;
        for (std::size_t c = 0; c < a.channels.size(); at += std::size_t(a.bytes[c]), ++c) {
            if (std::memcmp(&a.data[at], &b.data[at], std::size_t(a.bytes[c])) == 0) continue;
            if (differing++ == 0)
                first = "pixel (" + std::to_string(a.x + int(i % std::size_t(a.width))) + ", " +
                        std::to_string(a.y + int(i / std::size_t(a.width))) + ") channel " +
                        a.channels[c] + ": " + word(a.formats[c], &a.data[at], a.bytes[c]) +
                        " vs " + word(b.formats[c], &b.data[at], b.bytes[c]);
        }
    }
    if (differing == 0) return {};
    return first + "; " + std::to_string(differing) + " of " + std::to_string(words) +
           " words differ";
}

} // namespace

int main(int argc, char** argv) {
    if (argc == 2 && (std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0)) {
        std::cout << "usage: tandem-imgcmp A B [A2 B2 ...]\nExits 0 when each pair of images "
                     "stores the same words bit for bit, 1 when not (one line per pair that "
                     "differs: its first difference), 2 when a file cannot be read.\n";
        return 0;
    }
    if (argc < 3 || argc % 2 == 0) {
        std::cerr
            << "tandem-imgcmp: error: expected pairs of image files (usage: tandem-imgcmp A B "
               "[A2 B2 ...])"
            << std::endl;
        return 2;
    }
    int code = 0;
    try {
        for (int i = 1; i + 1 < argc; i += 2) {
            const StoredImage a = tandem::read_stored_image(argv[i]);
            const StoredImage b = tandem::read_stored_image(argv[i + 1]);
            const std::string d = difference(a, b);
            if (d.empty()) continue;
            std::cout << argv[i] << " " << argv[i + 1] << ": differ: " << d << std::endl;
            code = 1;
        }
    } catch (const std::exception& e) {
        std::cerr << "tandem-imgcmp: error: " << e.what() << std::endl;
        return 2;
    }
    return code;
}
