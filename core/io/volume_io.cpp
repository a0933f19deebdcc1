// Mitsuba's .vol grids (core/io/volume_io.h). No Debian library reads this format; it is 48 bytes
// of header and raw float32 values, read here with the bounds checks of core/io/binary.h.
#include "core/io/volume_io.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <string_view>

#include "core/io/atomic_file.h"
#include "core/io/binary.h"
#include "runtime/error.h"

namespace tandem {

namespace {

constexpr std::size_t k_header_bytes = 3 + 1 + 4 * 5 + 4 * 6;
/// At most 2^31 values (8 GiB of float32): a resolution past it is a damaged header.
constexpr std::uint64_t k_max_values = std::uint64_t(1) << 31;

} // namespace

void check_grid_shape(const VolumeGrid& g, const std::string& where) {
    if (g.width < 2 || g.height < 2 || g.depth < 2)
        throw Error(where + ": resolution " + std::to_string(g.width) + " x " +
                    std::to_string(g.height) + " x " + std::to_string(g.depth) +
                    ": at least 2 voxels on each axis");
    if (g.channels != 1 && g.channels != 3)
        throw Error(where + ": " + std::to_string(g.channels) +
                    " channels: a grid has 1 (a scalar field) or 3 (RGB)");
    if (std::uint64_t(g.width) * std::uint64_t(g.height) * std::uint64_t(g.depth) *
            std::uint64_t(g.channels) > k_max_values)
        throw Error(where + ": resolution " + std::to_string(g.width) + " x " +
                    std::to_string(g.height) + " x " + std::to_string(g.depth) +
                    " is too large (at most 2^31 values)");
    for (int a = 0; a < 3; ++a)
        if (!std::isfinite(g.bbox_min[a]) || !std::isfinite(g.bbox_max[a]) ||
            !(g.bbox_min[a] < g.bbox_max[a]))
            throw Error(where + ": the bounding box is empty or not finite on axis " +
                        std::string(1, "xyz"[a]));
}

void check_finite(const VolumeGrid& g, const std::string& where) {
    for (std::size_t i = 0; i < g.values.size(); ++i)
        if (!std::isfinite(g.values[i])) {
            const std::size_t voxel = i / std::size_t(g.channels);
            const std::size_t x = voxel % std::size_t(g.width);
            const std::size_t y = voxel / std::size_t(g.width) % std::size_t(g.height);
            const std::size_t z = voxel / (std::size_t(g.width) * std::size_t(g.height));
            throw Error(where + ": a non-finite value at voxel (" + std::to_string(x) + ", " +
                        std::to_string(y) + ", " + std::to_string(z) + ")");
        }
}

VolumeGrid read_volume(const std::string& path) {
    if (path.size() > 4 && path.compare(path.size() - 4, 4, ".vdb") == 0) return read_vdb(path);
    const std::string data = read_file(path);
    const std::string_view bytes(data);
    std::size_t pos = 0;
    if (bytes.substr(0, 3) != "VOL") throw Error(path + ": not a Mitsuba volume (no 'VOL' magic)");
    pos = 3;
    const auto version = take_bytes<std::uint8_t>(bytes, pos, path);
    if (version != 3)
        throw Error(path + ": volume version " + std::to_string(version) + ": only 3 is read");
    const auto encoding = take_bytes<std::int32_t>(bytes, pos, path);
    if (encoding != 1)
        throw Error(path + ": volume encoding " + std::to_string(encoding) +
                    ": only 1 (float32) is read");
    VolumeGrid g;
    g.width = take_bytes<std::int32_t>(bytes, pos, path);
    g.height = take_bytes<std::int32_t>(bytes, pos, path);
    g.depth = take_bytes<std::int32_t>(bytes, pos, path);
    g.channels = take_bytes<std::int32_t>(bytes, pos, path);
    for (float& v : g.bbox_min) v = take_bytes<float>(bytes, pos, path);
    for (float& v : g.bbox_max) v = take_bytes<float>(bytes, pos, path);
    check_grid_shape(g, path);
    const std::size_t count = g.voxels() * std::size_t(g.channels);
    if (data.size() - k_header_bytes != count * sizeof(float))
        throw Error(path + ": " + std::to_string(data.size() - k_header_bytes) +
                    " bytes of values, the header's " + std::to_string(g.width) + " x " +
                    std::to_string(g.height) + " x " + std::to_string(g.depth) + " x " +
                    std::to_string(g.channels) + " need " + std::to_string(count * sizeof(float)));
    g.values.resize(count);
    std::memcpy(g.values.data(), data.data() + k_header_bytes, count * sizeof(float));
    check_finite(g, path);
    return g;
}

std::string volume_bytes(const VolumeGrid& g) {
    check_grid_shape(g, "volume");
    if (g.values.size() != g.voxels() * std::size_t(g.channels))
        throw Error("volume: " + std::to_string(g.values.size()) + " values for " +
                    std::to_string(g.voxels() * std::size_t(g.channels)));
    for (float v : g.values)
        if (!std::isfinite(v)) throw Error("volume: a non-finite value");
    std::string out = "VOL";
    put_bytes<std::uint8_t>(out, 3);
    for (std::int32_t v : {1, g.width, g.height, g.depth, g.channels}) put_bytes(out, v);
    for (float v : g.bbox_min) put_bytes(out, v);
    for (float v : g.bbox_max) put_bytes(out, v);
    out.append(reinterpret_cast<const char*>(g.values.data()), g.values.size() * sizeof(float));
    return out;
}

void write_volume(const std::string& path, const VolumeGrid& grid) {
    write_file_atomic(path, volume_bytes(grid));
}

} // namespace tandem
