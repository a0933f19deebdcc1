// Mitsuba's binary grid volumes (.vol, version 3): what <volume type="gridvolume"> reads for a
// heterogeneous medium's density or albedo.
//
// The layout (Mitsuba 3, src/volumes/grid.cpp), little-endian:
//   "VOL", u8 version (3), i32 encoding (1: float32), i32 x, y, z resolution, i32 channels,
//   6 float32 bounding box (min x, y, z, max x, y, z), then x y z channels float32 values,
//   channel fastest, then x, then y, then z: value (x, y, z, c) at ((z Y + y) X + x) C + c.
// Checked against Mitsuba 3.9.1's own reader (mi.VolumeGrid, scalar_rgb): it reads the file of
// tests/core/io/test_volume_io.cpp's layout case as a (z, y, x, c) array with these values, and
// writes a grid of them with the same bytes but for the bounding box (its own is the unit cube).
#pragma once

#include <array>
#include <string>
#include <vector>

namespace tandem {

struct VolumeGrid {
    int width = 0, height = 0, depth = 0; ///< x, y, z resolution
    int channels = 1;                     ///< 1 (a scalar field) or 3 (RGB)
    std::array<float, 3> bbox_min{0.0f, 0.0f, 0.0f}, bbox_max{1.0f, 1.0f, 1.0f};
    std::vector<float> values; ///< width height depth channels, channel fastest, then x, y, z
    /// An OpenVDB grid's own placement: the affine map (column-major 4x4) of the unit cube onto
    /// the grid's voxels in its index-to-world transform, which the volume's to_world then
    /// places (a .vol has none: `placed` false).
    bool placed = false;
    std::array<float, 16> to_world{};

    std::size_t voxels() const { return std::size_t(width) * height * depth; }
    float at(int x, int y, int z, int c = 0) const {
        return values[((std::size_t(z) * height + y) * width + x) * channels + c];
    }
};

/// Reads a grid file: an OpenVDB .vdb (read_vdb), else a .vol. A .vol: throws Error "PATH: what" for a file that is not one (magic, version,
/// encoding), a resolution below 2 on an axis or too large, channels other than 1 or 3, an empty
/// or inverted bounding box, a file shorter or longer than its header says, and a non-finite
/// value (naming the voxel). Whether values may be negative is the medium's to say.
VolumeGrid read_volume(const std::string& path);

/// Reads an OpenVDB file through the OpenVDB library (Debian's libopenvdb-dev): its grid named
/// "density", else its first float or vec3s grid, as the dense block of its active voxels'
/// bounding box (inactive voxels read as the background; an axis of one voxel is widened to two),
/// 1 or 3 channels, placed by the grid's linear index-to-world transform (`to_world`). Throws
/// Error "PATH: what" for a file OpenVDB cannot read, no such grid, no active voxel, a
/// non-linear transform, a block too large, or a non-finite value (naming the voxel).
VolumeGrid read_vdb(const std::string& path);

/// Throws Error "WHERE: a non-finite value at voxel (x, y, z)" for the first such value of g.
void check_finite(const VolumeGrid& g, const std::string& where);

/// Throws Error "WHERE: ..." where g's resolution, channels or bounding box are not those of a
/// grid read_volume accepts.
void check_grid_shape(const VolumeGrid& g, const std::string& where);

/// The bytes of `grid` as a .vol file (checked as read_volume checks them; throws Error).
std::string volume_bytes(const VolumeGrid& grid);

/// Writes `grid` to `path` atomically (write_file_atomic).
void write_volume(const std::string& path, const VolumeGrid& grid);

} // namespace tandem
