// Device layout of a scene for the path tracer: camera, materials, per-triangle records,
// emissive triangles with their alias table, and the render parameters. Shared by host and device.
#ifndef TANDEM_SHARED_SCENE_LAYOUT_H
#define TANDEM_SHARED_SCENE_LAYOUT_H

#include "shared/compat.h"

TANDEM_NAMESPACE_BEGIN

/// Pinhole camera, 96 bytes. A film position (fx, fy) in [0, 1]^2 (x right, y down) maps to the
/// world-space direction dir_z + (1 - 2 fx) dir_x + (1 - 2 fy) dir_y, as Mitsuba's perspective
/// sensor (camera +x points left). dir_x and dir_y are pre-scaled by the half-extents of the image
/// plane at distance 1.
typedef struct DeviceCamera {
    float4 origin; ///< world space; w unused
    float4 dir_x;  ///< world space, camera +x times tan(half fov x)
    float4 dir_y;  ///< world space, camera +y times tan(half fov y)
    float4 dir_z;  ///< world space, unit forward
    float near_clip;
    float far_clip;
    uint width;
    uint height;
    uint medium; ///< the medium the camera sits in (index into media), or NO_MEDIUM
    uint pad0;
    uint pad1;
    uint pad2;
} DeviceCamera;
TANDEM_STATIC_ASSERT_SIZE(DeviceCamera, 96);

#define MATERIAL_DIFFUSE 0u
#define MATERIAL_CONDUCTOR 1u
#define MATERIAL_ROUGHCONDUCTOR 2u
#define MATERIAL_DIELECTRIC 3u
#define MATERIAL_ROUGHPLASTIC 4u
/// Mitsuba's `null` bsdf: an index-matched boundary that rays pass straight through (a medium's
/// surface). Scenes with one are built with HAS_MEDIA (kernels/path/media.h).
#define MATERIAL_NULL 5u
#define MATERIAL_FLAG_TWOSIDED 1u
#define MATERIAL_FLAG_NONLINEAR 2u
/// A diffuse of constant reflectance 0 that is not a parameter (an emitter's default bsdf): it
/// reflects nothing, so paths end at it.
#define MATERIAL_FLAG_BLACK 4u
#define NO_TEXTURE 0xFFFFFFFFu
/// No entry in the parameter buffer: the value lives in the struct itself.
#define NO_PARAM 0xFFFFFFFFu

/// One BSDF, 96 bytes (Mitsuba's parameters; colours are linear RGB). The differentiable ones are
/// read from the flat parameter buffer (core/scene/params.h) at the *_param offsets when those are not
/// NO_PARAM; the struct keeps the values the scene was loaded with.
typedef struct Material {
    float4 reflectance; ///< diffuse: reflectance; roughplastic: diffuse_reflectance
    float4 specular;    ///< conductors, dielectric, roughplastic: specular_reflectance
    float4 eta;         ///< conductors: real IOR per channel; dielectric, roughplastic: .x = int/ext IOR
    float4 k;           ///< conductors: imaginary IOR per channel
    uint type;          ///< MATERIAL_*
    uint flags;         ///< MATERIAL_FLAG_*
    float alpha;        ///< GGX roughness (rough types)
    uint texture;       ///< texture of `reflectance`, or NO_TEXTURE
    uint reflectance_param; ///< rgb of an untextured `reflectance` in the parameter buffer
    uint specular_param;    ///< rgb of `specular`
    uint alpha_param;       ///< `alpha`
    uint plastic_table;     ///< roughplastic: first float of its eta's table in plastic_tables
} Material;
TANDEM_STATIC_ASSERT_SIZE(Material, 96);

#define NO_EMITTER 0xFFFFFFFFu
/// No medium: vacuum (a camera, or a side of a shape, that has none).
#define NO_MEDIUM 0xFFFFFFFFu

/// What a primitive is made of, 16 bytes, indexed by primitive id.
typedef struct TriangleInfo {
    uint material; ///< index into materials
    uint emitter;  ///< index into emissive triangles, or NO_EMITTER
    /// The media of its shape's sides: its interior (behind the front normal) and its exterior,
    /// indices into media or NO_MEDIUM; both NO_MEDIUM where the shape is not a medium transition
    /// (rays that cross it stay in the medium they were in, as in Mitsuba).
    uint interior;
    uint exterior;
} TriangleInfo;
TANDEM_STATIC_ASSERT_SIZE(TriangleInfo, 16);

/// An emissive triangle, 64 bytes: vertices (world space), emitting on the side its normal
/// (p1 - p0) x (p2 - p0) faces; (nx, ny, nz) is that normal, triangle_front_normal(p0, p1, p2)
/// (shared/sampling.h), computed by the host, at floats 12-14 as in ShadingPrimitive. p0.w holds
/// the area (world units squared). The radiance (linear RGB) is its emitter's parameter: three
/// floats at radiance_param in the parameter buffer.
typedef struct EmissiveTriangle {
    float4 p0;
    float4 p1;
    float4 p2;
    float nx, ny, nz;
    uint radiance_param;
} EmissiveTriangle;
TANDEM_STATIC_ASSERT_SIZE(EmissiveTriangle, 64);

#define DELTA_POINT 0u
#define DELTA_SPOT 1u

/// A point or spot light, 64 bytes (Mitsuba's `point` and `spot`). position.w: selection pmf (as
/// p1.w of an emissive triangle); intensity: radiant intensity, linear RGB; axis: world-space unit
/// spot direction with cos(cutoff_angle) in w. Spot falloff: 1 inside beam_width, then linear in
/// the angle down to 0 at cutoff_angle (Mitsuba's falloff curve).
typedef struct DeltaLight {
    float4 position;
    float4 intensity;
    float4 axis;
    float cos_beam;
    float cutoff;         ///< radians
    float inv_transition; ///< 1 / (cutoff - beam_width), radians
    uint type;            ///< DELTA_*
} DeltaLight;
TANDEM_STATIC_ASSERT_SIZE(DeltaLight, 64);

/// An environment map, 80 bytes (Mitsuba's `envmap`): a latitude-longitude image of linear RGB
/// radiance (already multiplied by `scale`), with to_local = the inverse rotation of to_world in
/// rows. A world direction d maps to local l = to_local d, then u = atan2(l.x, -l.z) / 2pi (mod 1),
/// v = acos(l.y) / pi. Texel (x, y) sits at u = (x + 1/2) / W (wrapping) and v = y / (H - 1)
/// (rows 0 and H - 1 at the poles), and the lookup is bilinear between the four around (u, v)
/// (Mitsuba's convention). Each texel's .w is its sampling weight, luminance times sin(theta),
/// normalised so that its bilinear interpolant is the sampling density in (u, v). The cell
/// between columns x, x + 1 and rows y, y + 1 is chosen by the marginal CDF over the H - 1 cell
/// rows (H entries at cdf_offset), then by that row's conditional CDF over its W cells (W + 1
/// entries each, after it).
typedef struct EnvMap {
    float4 to_local0;
    float4 to_local1;
    float4 to_local2;
    uint width;
    uint height;
    uint texel_offset; ///< first texel in the texel buffer
    uint cdf_offset;   ///< first marginal CDF entry in the CDF buffer
    float total;       ///< integral of the raw weights' interpolant (each .w was divided by it)
    uint pad0;
    uint pad1;
    uint pad2;
} EnvMap;
TANDEM_STATIC_ASSERT_SIZE(EnvMap, 80);

/// Texture coordinates of a primitive's three vertices, 32 bytes: uv01 = (u0, v0, u1, v1),
/// uv2 = (u2, v2, 0, 0). Meshes without uvs get Mitsuba's default (0,0), (1,0), (0,1).
typedef struct TriangleUV {
    float4 uv01;
    float4 uv2;
} TriangleUV;
TANDEM_STATIC_ASSERT_SIZE(TriangleUV, 32);

/// The shading normals of a primitive, 64 bytes (HAS_SHADING_NORMALS builds;
/// core/scene/vertex_normals.h): n0, n1, n2 (xyz) the unit normals of its three vertices,
/// interpolated at a hit with its barycentric weights. link.x: 1 where the primitive is shaded with
/// them, 0 where with its own normal (a flat shape, a sphere, a disk). link.y, .z, .w: for each
/// vertex whose normal is derived from the vertex positions, in builds with shape gradients, the
/// first of the NormalJacobian blocks of that normal; else NO_PARAM.
typedef struct TriangleNormals {
    float4 n0;
    float4 n1;
    float4 n2;
    uint4 link;
} TriangleNormals;
TANDEM_STATIC_ASSERT_SIZE(TriangleNormals, 64);

/// One block of the derivative of a derived vertex normal N with respect to a vertex position P,
/// 48 bytes: c0, c1, c2 (xyz) its columns dN/dP.x, dN/dP.y, dN/dP.z. c0.w: P's offset in the
/// parameters (as_float of a uint); c1.w: the blocks of N's list from this one to its end (as_float
/// of a uint: the first block holds their count).
typedef struct NormalJacobian {
    float4 c0;
    float4 c1;
    float4 c2;
} NormalJacobian;
TANDEM_STATIC_ASSERT_SIZE(NormalJacobian, 48);

#define TEXTURE_BITMAP 0u
#define TEXTURE_CHECKERBOARD 1u
#define TEXTURE_FILTER_BILINEAR 0u
#define TEXTURE_FILTER_NEAREST 1u

/// One texture, 96 bytes. Texture coordinates first go through to_uv: u' = dot(uv_row0.xyz,
/// (u, v, 1)), v' = dot(uv_row1.xyz, (u, v, 1)). Bitmaps: texels[offset + y * width + x] hold
/// linear RGB (decoded from sRGB on the host), texel (0, 0) at uv (0, 0), wrapping (repeat) in both
/// directions. A bitmap that is a parameter (param != NO_PARAM) reads its texels from the
/// parameter buffer instead: rgb triplets from param, same order. Checkerboard: color0 where the fractional parts of u' and v' are on the same side
/// of 1/2, color1 elsewhere (Mitsuba's checkerboard).
typedef struct TextureInfo {
    float4 color0;
    float4 color1;
    float4 uv_row0;
    float4 uv_row1;
    uint kind;   ///< TEXTURE_*
    uint offset; ///< first texel
    uint width;
    uint height;
    uint filter; ///< TEXTURE_FILTER_*
    uint param;  ///< first texel in the parameter buffer, or NO_PARAM
    uint pad1;
    uint pad2;
} TextureInfo;
TANDEM_STATIC_ASSERT_SIZE(TextureInfo, 96);

/// One alias-table slot, 8 bytes (Vose): keep slot i with probability q, else take `alias`.
typedef struct AliasEntry {
    float q;
    uint alias;
} AliasEntry;
TANDEM_STATIC_ASSERT_SIZE(AliasEntry, 8);

#define MEDIUM_HOMOGENEOUS 0u
#define MEDIUM_GRID 1u
#define PHASE_ISOTROPIC 0u
#define PHASE_HG 1u
#define NO_GRID 0xFFFFFFFFu

/// A grid of voxel values, 80 bytes: nx * ny * nz voxels of `channels` floats at `offset` in the
/// medium data buffer (majorant grids) or in the parameter buffer (a medium's sigma_t and albedo
/// grids, which are parameters), channels innermost, then x, then y, then z (Mitsuba's .vol order). It
/// covers the unit cube of its local space (to_local: rows of the world-to-local affine map, the
/// inverse of its volume's to_world); voxel centres sit at ((i + 1/2) / nx, ...), and lookups are
/// trilinear with clamping at the faces (Mitsuba's gridvolume: filter_type "trilinear",
/// wrap_mode "clamp"; kernels/shared/medium.h).
typedef struct DeviceGrid {
    float4 to_local0;
    float4 to_local1;
    float4 to_local2;
    uint offset;
    uint nx;
    uint ny;
    uint nz;
    uint channels; ///< 1 or 3
    uint pad0;
    uint pad1;
    uint pad2;
} DeviceGrid;
TANDEM_STATIC_ASSERT_SIZE(DeviceGrid, 80);

/// A participating medium, 80 bytes (Mitsuba's `homogeneous` and `heterogeneous`).
/// Homogeneous: extinction sigma_t (rgb) times `scale`, and single-scattering albedo, constant.
/// Grid (heterogeneous): sigma_t(x) = scale * the sigma_t grid at x (empty outside the grid's unit
/// cube), albedo from the albedo grid or the constant. The majorant grid (one channel, in the
/// sigma_t grid's local space) holds per coarse cell an upper bound of the sigma_t grid's
/// trilinear interpolant over the cell, every channel: free flights and ratio tracking draw their
/// tentative collisions from scale times that bound, cell by cell (kernels/path/media.h).
/// Differentiable values are read from the parameter buffer where their *_param is not NO_PARAM
/// (kernels/path/media.h: medium_load): sigma_t and albedo as rgb, or a grid's voxels (in the
/// grid's layout), scale and g as scalars.
typedef struct Medium {
    float4 sigma_t;     ///< homogeneous: rgb extinction before scale; grid: unused; .w: scale
    float4 albedo;      ///< rgb, where albedo_grid is NO_GRID
    uint kind;          ///< MEDIUM_*
    uint phase;         ///< PHASE_*
    float g;            ///< Henyey-Greenstein asymmetry (PHASE_HG)
    float majorant;     ///< grid: scale times the largest cell of the majorant grid (host checks)
    uint sigma_t_grid;  ///< grid: index into grids
    uint albedo_grid;   ///< index into grids, or NO_GRID
    uint majorant_grid; ///< grid: index into grids
    uint sigma_t_param; ///< rgb sigma_t, or the sigma_t grid's voxels, in the parameters
    uint albedo_param;  ///< rgb albedo, or the albedo grid's voxels, in the parameters
    uint scale_param;   ///< scale in the parameters
    uint g_param;       ///< g in the parameters (PHASE_HG)
    uint pad0;
} Medium;
TANDEM_STATIC_ASSERT_SIZE(Medium, 80);

/// Per-launch parameters, 48 bytes.
typedef struct RenderParams {
    uint env_param;      ///< rgb radiance of a constant environment in the parameter buffer
    uint pad0;
    uint pad1;
    uint pad2;
    uint seed;
    uint sample_begin;   ///< first sample index of this pass
    uint sample_count;   ///< samples per pixel in this pass
    uint max_depth;      ///< longest path in segments; 0xFFFFFFFF = unbounded
    uint rr_depth;       ///< path length from which Russian roulette applies
    uint emissive_count; ///< number of emissive triangles
    float light_env_prob; ///< probability that NEE samples the environment instead of a triangle
    uint delta_count;     ///< point and spot lights; alias slots emissive_count.. are theirs
} RenderParams;
TANDEM_STATIC_ASSERT_SIZE(RenderParams, 48);

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_SCENE_LAYOUT_H
