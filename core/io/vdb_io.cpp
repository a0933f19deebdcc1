// OpenVDB grids for heterogeneous media, read through the OpenVDB library (volume_io.h).
#include <algorithm>
#include <mutex>

#include <openvdb/openvdb.h>

#include "core/io/volume_io.h"
#include "runtime/error.h"
#include "runtime/stderr_redirect.h"

namespace tandem {

namespace {

/// The dense block [lo, hi] (index space, inclusive) of `grid` into g.values, channel fastest,
/// then x, y, z; inactive voxels read as the grid's background.
template <class Grid, class Read>
void dense_block(const Grid& grid, const openvdb::Coord& lo, VolumeGrid& g, Read read) {
    auto access = grid.getConstAccessor();
    g.values.resize(g.voxels() * std::size_t(g.channels));
    std::size_t i = 0;
    for (int z = 0; z < g.depth; ++z)
        for (int y = 0; y < g.height; ++y)
            for (int x = 0; x < g.width; ++x) {
                read(access.getValue(lo.offsetBy(x, y, z)), &g.values[i]);
                i += std::size_t(g.channels);
            }
}

} // namespace

VolumeGrid read_vdb(const std::string& path) {
    static std::once_flag initialized;
    std::call_once(initialized, [] { openvdb::initialize(); });
    openvdb::GridBase::Ptr base;
    try {
        // OpenVDB prints warnings about damaged files on std::cerr besides throwing: the error
        // stays one line
        StderrRedirect quiet(StderrRedirect::discard);
        openvdb::io::File file(path);
        file.open(false); // no delayed loading: the file is read whole, now
        openvdb::GridPtrVecPtr grids = file.getGrids();
        file.close();
        for (const openvdb::GridBase::Ptr& grid : *grids) {
            if (!grid || !(grid->isType<openvdb::FloatGrid>() || grid->isType<openvdb::Vec3SGrid>()))
                continue;
            if (!base || grid->getName() == "density") base = grid;
            if (grid->getName() == "density") break;
        }
    } catch (const openvdb::Exception& e) {
        throw Error(path + ": OpenVDB cannot read it: " + e.what());
    } catch (const std::exception& e) {
        throw Error(path + ": OpenVDB cannot read it: " + e.what());
    }
    if (!base) throw Error(path + ": no float or vec3s grid in the file");
    const std::string where = path + ": grid '" + base->getName() + "'";
    const openvdb::CoordBBox box = base->evalActiveVoxelBoundingBox();
    if (box.empty() || base->activeVoxelCount() == 0)
        throw Error(where + ": no active voxel");
    const openvdb::math::Transform& t = base->transform();
    if (!t.isLinear()) throw Error(where + ": a non-linear (frustum) transform is not supported");
    // an axis of one voxel is widened by one above (trilinear lookups need two)
    openvdb::Coord lo = box.min(), hi = box.max();
    for (int a = 0; a < 3; ++a)
        if (hi[a] == lo[a]) hi[a] += 1;
    VolumeGrid g;
    const openvdb::Coord dim = hi - lo + openvdb::Coord(1);
    g.width = dim.x();
    g.height = dim.y();
    g.depth = dim.z();
    g.channels = base->isType<openvdb::FloatGrid>() ? 1 : 3;
    check_grid_shape(g, where);
    if (g.channels == 1)
        dense_block(*openvdb::gridConstPtrCast<openvdb::FloatGrid>(base), lo, g,
                    [](float v, float* out) { *out = v; });
    else
        dense_block(*openvdb::gridConstPtrCast<openvdb::Vec3SGrid>(base), lo, g,
                    [](const openvdb::Vec3s& v, float* out) {
                        out[0] = v.x();
                        out[1] = v.y();
                        out[2] = v.z();
                    });
    check_finite(g, where);
    // The unit cube holds voxel i's centre at (i + 1/2) / n (shared/medium.h), which OpenVDB
    // puts at index lo + i: the cube is index space [lo - 1/2, hi + 1/2], then the grid's
    // linear transform takes it to its world.
    const openvdb::Mat4d index_to_world = t.baseMap()->getAffineMap()->getMat4();
    openvdb::Mat4d unit_to_index = openvdb::Mat4d::identity();
    for (int a = 0; a < 3; ++a) {
        unit_to_index(a, a) = double(dim[a]);
        unit_to_index(3, a) = double(lo[a]) - 0.5;
    }
    // OpenVDB composes row vectors (p' = p M): unit -> index -> world is unit_to_index * index_to_world
    const openvdb::Mat4d m = unit_to_index * index_to_world;
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r)
            g.to_world[std::size_t(c * 4 + r)] = float(m(c, r)); // column c of the column-vector map
    g.placed = true;
    for (int i = 0; i < 16; ++i)
        if (!std::isfinite(g.to_world[std::size_t(i)]))
            throw Error(where + ": its transform is not finite");
    g.bbox_min = {0.0f, 0.0f, 0.0f};
    g.bbox_max = {1.0f, 1.0f, 1.0f};
    return g;
}

} // namespace tandem
