// Bit-exact image comparison: read_stored_image (core/io/image_io.h) keeps the words a file
// stores, and tandem-imgcmp (cli/imgcmp.cpp) fails on any differing word, NaN payloads and the
// sign of zero included, where idiff -fail 0 passes NaN against 0.5 and +0 against -0.
#include <doctest/doctest.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

#include <OpenImageIO/imageio.h>

#include "core/io/image_io.h"

using namespace tandem;
namespace fs = std::filesystem;

namespace {

/// A fresh folder for this process's images, removed when the test program exits.
struct ScratchDir {
    fs::path dir = fs::temp_directory_path() / ("tandem-imgcmp-test-" + std::to_string(getpid()));
    ScratchDir() { fs::create_directories(dir); }
    ~ScratchDir() {
        std::error_code ec;
        fs::remove_all(dir, ec);
    }
};
const ScratchDir g_scratch;

float from_bits(std::uint32_t bits) {
    float f;
    std::memcpy(&f, &bits, 4);
    return f;
}

/// A 2x1 RGB float EXR (write_image, as Tandem writes every image) holding these six words.
std::string float_exr(const std::string& name, const std::vector<std::uint32_t>& words) {
    std::vector<float> rgb;
    for (std::uint32_t w : words)
        rgb.push_back(from_bits(w));
    const std::string path = (g_scratch.dir / name).string();
    write_image(path, 2, 1, rgb);
    return path;
}

/// A 2x1 RGB half EXR holding these six 16-bit words (OpenImageIO, as other tools write them).
std::string half_exr(const std::string& name, const std::vector<std::uint16_t>& words) {
    const std::string path = (g_scratch.dir / name).string();
    auto out = OIIO::ImageOutput::create(path);
    REQUIRE(out);
    REQUIRE(out->open(path, OIIO::ImageSpec(2, 1, 3, OIIO::TypeDesc::HALF)));
    REQUIRE(out->write_image(OIIO::TypeDesc::HALF, words.data()));
    REQUIRE(out->close());
    return path;
}

struct Run {
    int code;
    std::string output; ///< stdout and stderr
};

/// tandem-imgcmp FILES...
Run imgcmp_files(const std::vector<std::string>& files) {
    std::string command = TANDEM_IMGCMP;
    for (const std::string& f : files)
        command += " '" + f + "'";
    command += " 2>&1";
    FILE* p = popen(command.c_str(), "r");
    REQUIRE(p != nullptr);
    Run r{};
    char buffer[512];
    while (std::fgets(buffer, sizeof(buffer), p) != nullptr)
        r.output += buffer;
    const int status = pclose(p);
    REQUIRE(WIFEXITED(status));
    r.code = WEXITSTATUS(status);
    return r;
}

/// tandem-imgcmp A B.
Run imgcmp(const std::string& a, const std::string& b) {
    return imgcmp_files({a, b});
}

// Six words with the cases below in them: a quiet NaN, -0, a subnormal, 1, 0.5, +Inf.
const std::vector<std::uint32_t> k_words = {0x7fc00000u, 0x80000000u, 0x00000001u,
                                            0x3f800000u, 0x3f000000u, 0x7f800000u};

/// k_words with word `i` replaced by `w`.
std::vector<std::uint32_t> with(std::size_t i, std::uint32_t w) {
    std::vector<std::uint32_t> v = k_words;
    v[i] = w;
    return v;
}

} // namespace

TEST_CASE("read_stored_image: a float EXR's words as written, NaN payloads and -0 included") {
    const std::vector<std::uint32_t> words = {0x7fc00001u, 0xffc12345u, 0x80000000u,
                                              0x00000001u, 0x3f800001u, 0xff800000u};
    const StoredImage image = read_stored_image(float_exr("stored.exr", words));
    CHECK(image.width == 2);
    CHECK(image.height == 1);
    CHECK(image.channels == std::vector<std::string>{"R", "G", "B"});
    CHECK(image.formats == std::vector<std::string>{"float", "float", "float"});
    REQUIRE(image.data.size() == words.size() * 4);
    for (std::size_t i = 0; i < words.size(); ++i) {
        std::uint32_t got;
        std::memcpy(&got, &image.data[4 * i], 4);
        CHECK_MESSAGE(got == words[i], "word " << i);
    }
}

TEST_CASE("tandem-imgcmp: the same words pass, NaN and -0 among them") {
    const Run r = imgcmp(float_exr("same-a.exr", k_words), float_exr("same-b.exr", k_words));
    CHECK(r.code == 0);
    CHECK(r.output.empty());
}

TEST_CASE("tandem-imgcmp: NaN against 0.5 fails (idiff -fail 0 passes it)") {
    const Run r =
        imgcmp(float_exr("nan.exr", with(4, 0x7fc00000u)), float_exr("half.exr", k_words));
    CHECK(r.code == 1);
    CHECK(r.output.find(": differ: pixel (1, 0) channel G: 0x7fc00000 (nan) vs 0x3f000000 "
                        "(0.5); 1 of 6 words differ\n") != std::string::npos);
}

TEST_CASE("tandem-imgcmp: +0 against -0 fails") {
    const Run r = imgcmp(float_exr("plus0.exr", with(1, 0)), float_exr("minus0.exr", k_words));
    CHECK(r.code == 1);
    CHECK(r.output.find("pixel (0, 0) channel G: 0x00000000 (0) vs 0x80000000 (-0); 1 of 6") !=
          std::string::npos);
}

TEST_CASE("tandem-imgcmp: one ulp fails") {
    const Run r = imgcmp(float_exr("one.exr", k_words), float_exr("ulp.exr", with(3, 0x3f800001u)));
    CHECK(r.code == 1);
    CHECK(r.output.find("pixel (1, 0) channel R: 0x3f800000 (1) vs 0x3f800001 (1.00000012)") !=
          std::string::npos);
}

TEST_CASE("tandem-imgcmp: NaNs of different payloads fail, and every differing word is counted") {
    std::vector<std::uint32_t> other = with(0, 0x7fc00001u);
    other[5] = 0x7f800001u; // a signalling NaN where +Inf was
    const Run r = imgcmp(float_exr("nan-a.exr", k_words), float_exr("nan-b.exr", other));
    CHECK(r.code == 1);
    CHECK(r.output.find("pixel (0, 0) channel R: 0x7fc00000 (nan) vs 0x7fc00001 (nan); 2 of 6 "
                        "words differ") != std::string::npos);
}

TEST_CASE("tandem-imgcmp: a half EXR is compared by its 16-bit words") {
    const std::vector<std::uint16_t> ones = {0x3c00, 0x3c00, 0x3c00, 0x3c00, 0x3c00, 0x3c00};
    std::vector<std::uint16_t> ulp = ones;
    ulp[2] = 0x3c01;
    const std::string a = half_exr("half-a.exr", ones);
    CHECK(imgcmp(a, half_exr("half-same.exr", ones)).code == 0);
    const Run r = imgcmp(a, half_exr("half-ulp.exr", ulp));
    CHECK(r.code == 1);
    CHECK(r.output.find("pixel (0, 0) channel B: 0x3c00 (1) vs 0x3c01 (1.00097656); 1 of 6") !=
          std::string::npos);
    // the same values as floats are another format, not the same words
    const Run f =
        imgcmp(a, float_exr("float-ones.exr", std::vector<std::uint32_t>(6, 0x3f800000u)));
    CHECK(f.code == 1);
    CHECK(f.output.find("the channel formats are half,half,half and float,float,float") !=
          std::string::npos);
}

TEST_CASE("tandem-imgcmp: other sizes fail, and an unreadable file is one line and exit 2") {
    const std::string a = float_exr("size-a.exr", k_words);
    const std::string b = (g_scratch.dir / "size-b.exr").string();
    write_image(b, 1, 2, std::vector<float>(6, 0.25f));
    const Run r = imgcmp(a, b);
    CHECK(r.code == 1);
    CHECK(r.output.find("the images are 2x1 at (0, 0) and 1x2 at (0, 0)") != std::string::npos);
    const std::string missing = (g_scratch.dir / "missing.exr").string();
    const Run m = imgcmp(a, missing);
    CHECK(m.code == 2);
    CHECK(m.output.rfind("tandem-imgcmp: error: " + missing + ": cannot read image", 0) == 0);
    CHECK(m.output.find('\n') == m.output.size() - 1);
    CHECK(imgcmp(a, "").code == 2);
}

TEST_CASE("tandem-imgcmp: several pairs, one line for each that differs") {
    const std::string same = float_exr("pairs-same.exr", k_words);
    const std::string ulp = float_exr("pairs-ulp.exr", with(3, 0x3f800001u));
    const std::string zero = float_exr("pairs-zero.exr", with(1, 0));
    CHECK(imgcmp_files({same, same, ulp, ulp}).code == 0);
    const Run r = imgcmp_files({same, ulp, same, same, same, zero});
    CHECK(r.code == 1);
    CHECK(r.output == same + " " + ulp + ": differ: pixel (1, 0) channel R: 0x3f800000 (1) vs " +
                          "0x3f800001 (1.00000012); 1 of 6 words differ\n" + same + " " + zero +
                          ": differ: pixel (0, 0) channel G: 0x80000000 (-0) vs 0x00000000 (0); " +
                          "1 of 6 words differ\n");
    CHECK(imgcmp_files({same, ulp, same}).code == 2); // not pairs
    CHECK(imgcmp_files({same}).code == 2);
}
