// Mitsuba's .vol grids (core/io/volume_io.h): the layout against bytes built here by hand, a
// round trip, and each malformed file one Error naming the file.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string>

#include "core/io/atomic_file.h"
#include "core/io/volume_io.h"
#include "runtime/error.h"

using namespace tandem;
namespace fs = std::filesystem;

namespace {

std::string temp(const std::string& name) {
    const fs::path dir = fs::temp_directory_path() / "tandem-test-volume";
    fs::create_directories(dir);
    return (dir / name).string();
}

template <class T> void put(std::string& s, T v) {
    s.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

/// A .vol as Mitsuba 3 writes it, byte by byte: magic, version, encoding, resolution, channels,
/// bounding box, then the values in the order given.
std::string vol(std::int32_t x, std::int32_t y, std::int32_t z, std::int32_t c,
                const std::vector<float>& values, std::uint8_t version = 3,
                std::int32_t encoding = 1, float box_max_x = 2.0f) {
    std::string s = "VOL";
    put(s, version);
    for (std::int32_t v : {encoding, x, y, z, c}) put(s, v);
    for (float v : {-1.0f, 0.0f, 0.5f, box_max_x, 1.0f, 1.5f}) put(s, v);
    for (float v : values) put(s, v);
    return s;
}

std::string error_of(const std::string& name, const std::string& bytes) {
    const std::string path = temp(name);
    write_file_atomic(path, bytes);
    try {
        read_volume(path);
    } catch (const Error& e) {
        return e.what();
    }
    return "no error";
}

} // namespace

TEST_SUITE("volume files") {
    TEST_CASE("a .vol reads in Mitsuba's layout: channel fastest, then x, y, z") {
        // 2 x 3 x 2 voxels, 3 channels: value = 100 z + 10 y + x + c / 10, written in file order
        std::vector<float> values;
        for (int z = 0; z < 2; ++z)
            for (int y = 0; y < 3; ++y)
                for (int x = 0; x < 2; ++x)
                    for (int c = 0; c < 3; ++c) values.push_back(100.0f * z + 10.0f * y + x + c / 10.0f);
        const std::string path = temp("layout.vol");
        write_file_atomic(path, vol(2, 3, 2, 3, values));
        const VolumeGrid g = read_volume(path);
        CHECK(g.width == 2);
        CHECK(g.height == 3);
        CHECK(g.depth == 2);
        CHECK(g.channels == 3);
        CHECK(g.bbox_min == std::array<float, 3>{-1.0f, 0.0f, 0.5f});
        CHECK(g.bbox_max == std::array<float, 3>{2.0f, 1.0f, 1.5f});
        for (int z = 0; z < 2; ++z)
            for (int y = 0; y < 3; ++y)
                for (int x = 0; x < 2; ++x)
                    for (int c = 0; c < 3; ++c)
                        CHECK(g.at(x, y, z, c) == 100.0f * z + 10.0f * y + x + c / 10.0f);
        // and written back, the same bytes
        CHECK(volume_bytes(g) == vol(2, 3, 2, 3, values));
        const std::string copy = temp("copy.vol");
        write_volume(copy, g);
        CHECK(read_file(copy) == read_file(path));
    }

    TEST_CASE("a malformed .vol is one error naming the file and the problem") {
        const std::vector<float> eight(8, 0.5f);
        std::string bad_magic = vol(2, 2, 2, 1, eight);
        bad_magic[2] = 'X';
        std::string truncated_header = vol(2, 2, 2, 1, {});
        truncated_header.resize(20);
        std::vector<float> nan = eight;
        nan[5] = std::numeric_limits<float>::quiet_NaN(); // voxel (1, 0, 1)
        const struct {
            const char* name;
            std::string bytes;
            std::string message;
        } cases[] = {
            {"magic.vol", bad_magic, ": not a Mitsuba volume (no 'VOL' magic)"},
            {"version.vol", vol(2, 2, 2, 1, eight, 2), ": volume version 2: only 3 is read"},
            {"encoding.vol", vol(2, 2, 2, 1, eight, 3, 2),
             ": volume encoding 2: only 1 (float32) is read"},
            {"header.vol", truncated_header, ": truncated"},
            {"flat.vol", vol(2, 1, 2, 1, {0, 0, 0, 0}),
             ": resolution 2 x 1 x 2: at least 2 voxels on each axis"},
            {"negative.vol", vol(2, -2, 2, 1, {}),
             ": resolution 2 x -2 x 2: at least 2 voxels on each axis"},
            {"channels.vol", vol(2, 2, 2, 2, std::vector<float>(16, 0.0f)),
             ": 2 channels: a grid has 1 (a scalar field) or 3 (RGB)"},
            {"huge.vol", vol(1 << 20, 1 << 20, 2, 1, {}),
             ": resolution 1048576 x 1048576 x 2 is too large (at most 2^31 values)"},
            {"short.vol", vol(2, 2, 2, 1, {0, 0, 0, 0, 0, 0, 0}),
             ": 28 bytes of values, the header's 2 x 2 x 2 x 1 need 32"},
            {"long.vol", vol(2, 2, 2, 1, std::vector<float>(9, 0.0f)),
             ": 36 bytes of values, the header's 2 x 2 x 2 x 1 need 32"},
            {"box.vol", vol(2, 2, 2, 1, eight, 3, 1, -1.0f),
             ": the bounding box is empty or not finite on axis x"},
            {"nan.vol", vol(2, 2, 2, 1, nan), ": a non-finite value at voxel (1, 0, 1)"},
        };
        for (const auto& c : cases) {
            CAPTURE(c.name);
            const std::string msg = error_of(c.name, c.bytes);
            CHECK(msg == temp(c.name) + c.message);
        }
        CHECK_THROWS_WITH_AS(read_volume(temp("missing.vol")), doctest::Contains("missing.vol"),
                             Error);
    }
}
