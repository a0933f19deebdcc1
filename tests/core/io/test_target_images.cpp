// Target photographs (read_target_image, core/io/image_io.h): EXR linear, PNG and JPEG decoded
// from sRGB, a mask from the image's alpha (unassociated: the colour is not premultiplied) or
// from a separate file, and every bad input refused in one line naming the file.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <unistd.h>
#include <vector>

#include <OpenImageIO/imageio.h>

#include "core/io/image_io.h"
#include "runtime/error.h"

using namespace tandem;
namespace fs = std::filesystem;

namespace {

/// A fresh folder for this process's images, removed when the test program exits.
struct ScratchDir {
    fs::path dir = fs::temp_directory_path() / ("tandem-target-test-" + std::to_string(getpid()));
    ScratchDir() { fs::create_directories(dir); }
    ~ScratchDir() {
        std::error_code ec;
        fs::remove_all(dir, ec);
    }
};
const ScratchDir g_scratch;

std::string scratch(const std::string& name) {
    return (g_scratch.dir / name).string();
}

// The sRGB curve (IEC 61966-2-1), in double: the reference the reader's float decoding is held to.
double srgb_encode(double v) {
    v = std::clamp(v, 0.0, 1.0);
    return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
}
double srgb_decode(double e) {
    e = std::clamp(e, 0.0, 1.0);
    return e <= 0.04045 ? e / 12.92 : std::pow((e + 0.055) / 1.055, 2.4);
}
/// The linear value of an 8-bit sRGB code.
double decode_code(int code) {
    return srgb_decode(code / 255.0);
}

/// Writes `data` (channels interleaved, row-major from the top left) with OpenImageIO: `channels`
/// channels of `format`, the alpha channel's index if any, a JPEG quality if above 0.
template <class T>
void write_oiio(const std::string& path, int w, int h, int channels, OIIO::TypeDesc format,
                const std::vector<T>& data, int alpha_channel = -1, int jpeg_quality = 0) {
    auto out = OIIO::ImageOutput::create(path);
    REQUIRE(out);
    OIIO::ImageSpec spec(w, h, channels, format);
    spec.alpha_channel = alpha_channel;
    if (alpha_channel >= 0) spec.channelnames[alpha_channel] = "A";
    // the colour as given, unassociated (OpenImageIO's PNG writer would divide it by alpha)
    if (alpha_channel >= 0) spec.attribute("oiio:UnassociatedAlpha", 1);
    if (jpeg_quality > 0) spec.attribute("Compression", "jpeg:" + std::to_string(jpeg_quality));
    REQUIRE(out->open(path, spec));
    REQUIRE(out->write_image(format, data.data()));
    REQUIRE(out->close());
}

/// The message read_target_image throws; fails the test when it throws nothing.
std::string error_of(const std::string& path, const std::string& mask, unsigned w, unsigned h) {
    try {
        read_target_image(path, mask, w, h, "the sensor 'cam0'");
    } catch (const Error& e) {
        return e.what();
    }
    FAIL("no error for " << path << " (mask '" << mask << "')");
    return {};
}

/// One line naming `file` and saying `what`.
void check_one_line(const std::string& message, const std::string& file, const std::string& what) {
    INFO(message);
    CHECK(message.find('\n') == std::string::npos);
    CHECK(message.rfind(file + ": ", 0) == 0);
    CHECK(message.find(what) != std::string::npos);
}

} // namespace

TEST_CASE("targets: a PNG agrees with the EXR of the same linear image within 8-bit sRGB "
          "quantisation") {
    const int w = 32, h = 4;
    std::vector<float> rgb(std::size_t(w) * h * 3);
    for (std::size_t i = 0; i < rgb.size(); ++i) // [0, 1], dense near 0 (the curve's linear part)
        rgb[i] = float(std::pow(double(i) / double(rgb.size() - 1), 3.0));
    const std::string exr = scratch("linear.exr"), png = scratch("linear.png");
    write_image(exr, w, h, rgb);
    write_image(png, w, h, rgb); // sRGB-encoded, 8 bits
    const TargetImage a = read_target_image(exr, "", w, h, "the sensor 'cam0'");
    const TargetImage b = read_target_image(png, "", w, h, "the sensor 'cam0'");
    CHECK(a.mask.empty());
    CHECK(b.mask.empty());
    REQUIRE(a.rgb == rgb); // EXR: linear, bit for bit
    REQUIRE(b.rgb.size() == rgb.size());
    for (std::size_t i = 0; i < rgb.size(); ++i) {
        // The PNG holds round(255 encode(v)), within half a code of encode(v): decoded, within the
        // larger of the curve's distances from v half a code either side (it is monotonic), plus
        // float rounding (the writer's and reader's curves are float).
        const double v = rgb[i], e = srgb_encode(v);
        const double bound = std::max(std::abs(srgb_decode(e + 0.5 / 255) - v),
                                      std::abs(srgb_decode(e - 0.5 / 255) - v)) +
                             1e-6 * (1 + v);
        INFO("value " << i << ": " << v << " read from the PNG as " << b.rgb[i]);
        CHECK(std::abs(b.rgb[i] - v) <= bound);
    }
}

TEST_CASE("targets: a JPEG is decoded from sRGB") {
    // Linear 0.5 is sRGB 0.7354, code 188 (187.52 rounded). A flat grey image at quality 100:
    // each 8x8 block is its DC coefficient alone, quantised by a step of 1 (exact), and grey has
    // Y = 188, Cb = Cr = 128 exactly, so the decoder returns 188, or one code off from the
    // rounding of its YCbCr to RGB conversion. Hence the bound: one code step at 188.
    const int w = 16, h = 16, code = 188;
    REQUIRE(std::lround(255 * srgb_encode(0.5)) == code);
    const std::string jpg = scratch("grey.jpg");
    write_oiio(jpg, w, h, 3, OIIO::TypeDesc::UINT8,
               std::vector<std::uint8_t>(std::size_t(w) * h * 3, std::uint8_t(code)), -1, 100);
    const TargetImage t = read_target_image(jpg, "", w, h, "the sensor 'cam0'");
    CHECK(t.mask.empty());
    REQUIRE(t.rgb.size() == std::size_t(w) * h * 3);
    const double step = decode_code(code + 1) - decode_code(code);
    for (float v : t.rgb) {
        INFO("read " << v << ", code 188 decodes to " << decode_code(code));
        CHECK(std::abs(v - decode_code(code)) <= step + 1e-6);
        // 0.5 itself: the code's own half-step quantisation on top
        CHECK(std::abs(v - 0.5) <= step + std::abs(decode_code(code) - 0.5) + 1e-6);
    }
    // not the sRGB value taken as linear (188 / 255 = 0.737)
    CHECK(std::abs(t.rgb[0] - 0.5f) < 0.01f);
}

namespace {

/// An 8x4 RGBA PNG: colour codes varying by pixel and channel, alpha 0 on the left half,
/// 255 on the right, and 128 (a half) at column 7 of row 0.
const int k_w = 8, k_h = 4;
int colour_code(std::size_t pixel, int k) {
    return int((pixel * 37 + std::size_t(k) * 71 + 20) % 256);
}
int alpha_code(std::size_t pixel) {
    const std::size_t x = pixel % k_w;
    return pixel == 7 ? 128 : x < k_w / 2 ? 0 : 255;
}
std::string rgba_png() {
    const std::string path = scratch("rgba.png");
    std::vector<std::uint8_t> data;
    for (std::size_t i = 0; i < std::size_t(k_w) * k_h; ++i) {
        for (int k = 0; k < 3; ++k)
            data.push_back(std::uint8_t(colour_code(i, k)));
        data.push_back(std::uint8_t(alpha_code(i)));
    }
    write_oiio(path, k_w, k_h, 4, OIIO::TypeDesc::UINT8, data, 3);
    return path;
}

/// The colour of every pixel is its stored code decoded from sRGB: not premultiplied by alpha.
void check_unassociated_colour(const TargetImage& t) {
    REQUIRE(t.rgb.size() == std::size_t(k_w) * k_h * 3);
    for (std::size_t i = 0; i < std::size_t(k_w) * k_h; ++i)
        for (int k = 0; k < 3; ++k) {
            INFO("pixel " << i << ", channel " << k << ", alpha " << alpha_code(i));
            CHECK(t.rgb[i * 3 + k] ==
                  doctest::Approx(decode_code(colour_code(i, k))).epsilon(1e-5));
        }
}

} // namespace

TEST_CASE("targets: a PNG's alpha is the mask, and its colour is not premultiplied") {
    const TargetImage t = read_target_image(rgba_png(), "", k_w, k_h, "the sensor 'cam0'");
    check_unassociated_colour(t);
    REQUIRE(t.mask.size() == std::size_t(k_w) * k_h);
    for (std::size_t i = 0; i < t.mask.size(); ++i) {
        INFO("pixel " << i);
        // linear, not sRGB-decoded: 128 / 255, not 0.216
        CHECK(t.mask[i] == doctest::Approx(alpha_code(i) / 255.0).epsilon(1e-6));
    }
    CHECK(t.mask[0] == 0.0f);
    CHECK(t.mask[k_w - 2] == 1.0f);

    SUBCASE("grey + alpha") {
        const std::string path = scratch("grey_alpha.png");
        std::vector<std::uint8_t> data;
        for (std::size_t i = 0; i < std::size_t(k_w) * k_h; ++i) {
            data.push_back(std::uint8_t(colour_code(i, 0)));
            data.push_back(std::uint8_t(alpha_code(i)));
        }
        write_oiio(path, k_w, k_h, 2, OIIO::TypeDesc::UINT8, data, 1);
        const TargetImage g = read_target_image(path, "", k_w, k_h, "the sensor 'cam0'");
        REQUIRE(g.mask.size() == std::size_t(k_w) * k_h);
        for (std::size_t i = 0; i < g.mask.size(); ++i) {
            INFO("pixel " << i);
            CHECK(g.mask[i] == doctest::Approx(alpha_code(i) / 255.0).epsilon(1e-6));
            for (int k = 0; k < 3; ++k) // grey in every channel, unassociated
                CHECK(g.rgb[i * 3 + k] ==
                      doctest::Approx(decode_code(colour_code(i, 0))).epsilon(1e-5));
        }
    }
    SUBCASE("an EXR's alpha, and its colour as stored") {
        const std::string path = scratch("rgba.exr");
        const std::vector<float> data = {0.1f, 0.2f, 0.3f, 0.0f, 4.0f, 5.0f,
                                         6.0f, 0.5f, 0.7f, 0.8f, 0.9f, 1.0f};
        write_oiio(path, 3, 1, 4, OIIO::TypeDesc::FLOAT, data, 3);
        const TargetImage e = read_target_image(path, "", 3, 1, "the sensor 'cam0'");
        CHECK(e.rgb == std::vector<float>{0.1f, 0.2f, 0.3f, 4.0f, 5.0f, 6.0f, 0.7f, 0.8f, 0.9f});
        CHECK(e.mask == std::vector<float>{0.0f, 0.5f, 1.0f});
    }
}

TEST_CASE("targets: a mask file overrides the image's alpha") {
    const std::string image = rgba_png();
    SUBCASE("an 8-bit grey mask, taken as stored (not sRGB-decoded)") {
        const std::string mask = scratch("mask.png");
        std::vector<std::uint8_t> data(std::size_t(k_w) * k_h, 255);
        data[0] = 0;  // opaque in the alpha: excluded by the mask
        data[5] = 51; // 0.2
        write_oiio(mask, k_w, k_h, 1, OIIO::TypeDesc::UINT8, data);
        const TargetImage t = read_target_image(image, mask, k_w, k_h, "the sensor 'cam0'");
        check_unassociated_colour(t); // the alpha is not used, and not applied either
        REQUIRE(t.mask.size() == data.size());
        for (std::size_t i = 0; i < data.size(); ++i) {
            INFO("pixel " << i);
            CHECK(t.mask[i] == doctest::Approx(data[i] / 255.0).epsilon(1e-6));
        }
        CHECK(t.mask[0] == 0.0f);
        CHECK(t.mask[1] == 1.0f); // transparent in the image's alpha
    }
    SUBCASE("an EXR mask: the first channel") {
        const std::string mask = scratch("mask.exr");
        std::vector<float> data;
        for (std::size_t i = 0; i < std::size_t(k_w) * k_h; ++i)
            for (float v : {float(i % 5) / 4.0f, 7.0f, -3.0f}) // only the first is the mask's
                data.push_back(v);
        write_oiio(mask, k_w, k_h, 3, OIIO::TypeDesc::FLOAT, data);
        const TargetImage t = read_target_image(image, mask, k_w, k_h, "the sensor 'cam0'");
        check_unassociated_colour(t);
        REQUIRE(t.mask.size() == std::size_t(k_w) * k_h);
        for (std::size_t i = 0; i < t.mask.size(); ++i)
            CHECK(t.mask[i] == float(i % 5) / 4.0f);
    }
}

TEST_CASE("targets: every bad input is one line naming the file") {
    const std::string good = scratch("good.exr");
    write_image(good, 4, 2, std::vector<float>(4 * 2 * 3, 0.5f));
    auto mask_exr = [](const std::string& name, int w, int h, float bad, std::size_t at) {
        std::vector<float> data(std::size_t(w) * h, 1.0f);
        data[at] = bad;
        const std::string path = scratch(name);
        write_oiio(path, w, h, 1, OIIO::TypeDesc::FLOAT, data);
        return path;
    };

    SUBCASE("a missing file") {
        const std::string missing = scratch("missing.png");
        check_one_line(error_of(missing, "", 4, 2), missing, "cannot read image");
    }
    SUBCASE("a missing mask") {
        const std::string missing = scratch("missing_mask.png");
        check_one_line(error_of(good, missing, 4, 2), missing, "cannot read image");
    }
    SUBCASE("a size other than the film's") {
        const std::string message = error_of(good, "", 5, 2);
        check_one_line(message, good, "the target is 4x2, the sensor 'cam0' renders 5x2");
        CHECK(message == good + ": the target is 4x2, the sensor 'cam0' renders 5x2");
    }
    SUBCASE("a non-finite pixel") {
        std::vector<float> rgb(4 * 2 * 3, 0.5f);
        rgb[(1 * 4 + 2) * 3 + 1] = std::numeric_limits<float>::quiet_NaN(); // column 2, row 1
        const std::string nan = scratch("nan.exr");
        write_image(nan, 4, 2, rgb);
        check_one_line(error_of(nan, "", 4, 2), nan, "column 2, row 1");
        check_one_line(error_of(nan, "", 4, 2), nan, "not finite");
    }
    SUBCASE("a mask of another size") {
        const std::string mask = mask_exr("small_mask.exr", 4, 1, 1.0f, 0);
        check_one_line(error_of(good, mask, 4, 2), mask,
                       "the mask is 4x1, the sensor 'cam0' renders 4x2");
    }
    SUBCASE("a mask value above 1") {
        const std::string mask = mask_exr("mask_2.exr", 4, 2, 2.0f, 5); // column 1, row 1
        check_one_line(error_of(good, mask, 4, 2), mask, "column 1, row 1");
        check_one_line(error_of(good, mask, 4, 2), mask, "is 2, outside [0, 1]");
    }
    SUBCASE("a negative mask value") {
        const std::string mask = mask_exr("mask_negative.exr", 4, 2, -0.25f, 3);
        check_one_line(error_of(good, mask, 4, 2), mask, "column 3, row 0");
        check_one_line(error_of(good, mask, 4, 2), mask, "is -0.25, outside [0, 1]");
    }
    SUBCASE("a non-finite mask value") {
        const std::string mask =
            mask_exr("mask_inf.exr", 4, 2, std::numeric_limits<float>::infinity(), 6);
        check_one_line(error_of(good, mask, 4, 2), mask, "column 2, row 1");
        check_one_line(error_of(good, mask, 4, 2), mask, "not finite");
    }
    SUBCASE("an alpha out of range") {
        const std::string path = scratch("alpha_nan.exr");
        std::vector<float> data(4 * 2 * 4, 1.0f);
        data[4 * 4 + 3] = std::numeric_limits<float>::quiet_NaN(); // pixel 4: column 0, row 1
        write_oiio(path, 4, 2, 4, OIIO::TypeDesc::FLOAT, data, 3);
        check_one_line(error_of(path, "", 4, 2), path, "column 0, row 1");
        data[4 * 4 + 3] = 1.5f;
        write_oiio(path, 4, 2, 4, OIIO::TypeDesc::FLOAT, data, 3);
        check_one_line(error_of(path, "", 4, 2), path, "the alpha at column 0, row 1");
    }
    SUBCASE("a mask that excludes every pixel") {
        const std::string mask = scratch("mask_zero.exr");
        write_oiio(mask, 4, 2, 1, OIIO::TypeDesc::FLOAT, std::vector<float>(8, 0.0f));
        check_one_line(error_of(good, mask, 4, 2), mask, "0 at every pixel");
    }
    SUBCASE("a text file named .png") {
        const std::string text = scratch("text.png");
        std::ofstream(text) << "not an image\nat all\n";
        check_one_line(error_of(text, "", 4, 2), text, "cannot read image");
        check_one_line(error_of(good, text, 4, 2), text, "cannot read image");
    }
}
