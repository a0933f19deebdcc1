// A scene description flattened for the path tracer: all shapes merged into one world-space mesh
// (triangles, and analytic spheres and disks) with per-primitive material and emitter records, emissive triangles with an alias table, and the
// camera. The one place where host scene objects become device structs.
#pragma once

#include <vector>

#include "core/scene/mesh.h"
#include "core/scene/params.h"
#include "core/scene/scene.h"
#include "shared/scene_layout.h"

namespace tandem {

/// A shape that became triangles of the merged mesh (a mesh file, or a built-in shape
/// tessellated): its vertices and triangles are contiguous ranges of RenderScene::mesh, and its
/// vertex positions the parameter `NAME.vertex_positions` at `param` (x y z per vertex, in the
/// order of its vertices).
struct MeshShape {
    std::string name; ///< the shape's id, else "shape<index in the file>"
    unsigned first_vertex = 0, vertex_count = 0;
    unsigned first_triangle = 0, triangle_count = 0;
    unsigned param = NO_PARAM;
    /// shaded with vertex normals (mesh.normals over its vertices), else with its triangles' own
    bool smooth = false;
    /// its vertex normals are derived from its vertex positions and follow them
    /// (core/scene/vertex_normals.h)
    bool normals_derived = false;
};

struct RenderScene {
    TriangleMesh mesh;                           ///< every shape, world space (analytic_shapes)
    std::vector<gpu::TriangleInfo> infos;        ///< per primitive of mesh
    std::vector<MeshShape> mesh_shapes;          ///< the shapes that are triangles, in file order
    std::vector<gpu::TriangleUV> uvs;            ///< per primitive of mesh (zero for a sphere or disk)
    std::vector<gpu::TextureInfo> textures;      ///< the scene's textures, in file order
    std::vector<gpu::float4> texels;             ///< texels of bitmaps that are not parameters
    std::vector<gpu::Material> materials;        ///< scene bsdfs, then diffuse 0.5, then black
    std::vector<float> plastic_tables;           ///< roughplastic tables, one per IOR
    std::vector<gpu::EmissiveTriangle> emissive; ///< area-light triangles; p1.w = selection pmf
    std::vector<gpu::DeltaLight> delta_lights;   ///< point and spot lights; position.w = pmf
    std::vector<gpu::AliasEntry> alias;          ///< alias table over emissive, then delta, by power
    /// The sensors, in file order (SceneDesc::sensors), and their device records.
    std::vector<Camera> sensors{Camera{}};
    std::vector<gpu::DeviceCamera> cameras{gpu::DeviceCamera{}};
    const gpu::DeviceCamera& camera() const { return cameras.front(); } ///< sensor 0's
    unsigned env_param = NO_PARAM; ///< radiance of a constant environment in `params`
    bool has_env = false;         ///< a constant environment or an environment map
    bool has_envmap = false;      ///< the environment is `envmap`, not `constant`
    gpu::EnvMap envmap{};
    std::vector<gpu::float4> env_texels; ///< rgb: radiance times scale; w: sampling weight
    std::vector<float> env_cdf;          ///< marginal CDF, then one conditional CDF per cell row
    std::vector<gpu::Medium> media;       ///< SceneDesc::media, in order (core/scene/media.cpp)
    std::vector<gpu::DeviceGrid> grids;   ///< the media's grids, then their majorant grids
    std::vector<float> medium_data;       ///< the majorant grids' values
    int max_depth = -1, rr_depth = 5;
    int spp = 4; ///< sensor 0's sample count (each sensor's: sensors[k].spp)
    /// The differentiable values (materials, bitmap texels, emitted radiance) the kernels read,
    /// built first; the device records above hold their offsets.
    ParamRegistry params;
    /// The mesh shape whose vertex positions `p` is; throws Error naming p otherwise.
    const MeshShape& mesh_shape(const Parameter& p) const;
    /// The triangles of mesh shape `s`, three indices each into its own vertices (0 is its
    /// first), flattened.
    std::vector<unsigned> shape_triangles(const MeshShape& s) const;
};

/// Flattens `desc`, loading bitmaps. Spheres and disks become analytic where they can (no
/// emitter; a sphere rotated and scaled evenly; a disk rotated and scaled evenly in its plane),
/// and are tessellated otherwise, or when `analytic_shapes` is false (a reference for tests). Throws Error "FILE:LINE: ..." for what the
/// renderer does not support yet (textured specular_reflectance), out-of-range parameters, and
/// unreadable textures or environment maps.
RenderScene build_render_scene(const SceneDesc& desc, bool analytic_shapes = true);

/// Flattens desc.media into out.media, grids and medium_data, loading the grid files: each grid
/// medium gets a majorant grid (build_majorant_grid). Throws Error "FILE:LINE: ..." naming the
/// medium, with the grid file's own message (core/io/volume_io.h) for a file that is not one, and
/// for negative or non-finite extinction and albedo outside [0, 1].
void build_media(const SceneDesc& desc, RenderScene& out);

/// The majorant grid of a grid of nx ny nz voxels of `channels` values (channels innermost, then
/// x, y, z): a coarse grid over the same unit cube, each cell the largest value of every voxel that
/// the trilinear interpolant over the cell blends (shared/medium.h: grid_axis), every channel, so
/// that it bounds the interpolant. cells_x, cells_y, cells_z: its resolution.
std::vector<float> build_majorant_grid(const std::vector<float>& values, unsigned nx, unsigned ny,
                                       unsigned nz, unsigned channels, unsigned cells_x,
                                       unsigned cells_y, unsigned cells_z);

/// Vose's alias table for sampling i with probability weights[i] / sum (weights >= 0, sum > 0).
std::vector<gpu::AliasEntry> build_alias_table(const std::vector<double>& weights);

/// The device record, texels and importance-sampling tables of an environment map (w x h linear
/// RGB, padded to at least 2 x 3 as Mitsuba). Throws Error when it has nothing to sample.
void build_envmap(const std::vector<float>& rgb, int w, int h, const glm::mat4& to_world,
                  RenderScene& out);

/// The device camera of `camera` (Mitsuba's perspective sensor conventions).
gpu::DeviceCamera make_device_camera(const Camera& camera);

} // namespace tandem
