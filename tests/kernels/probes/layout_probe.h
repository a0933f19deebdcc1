// The list of shared structs and fields whose size and offsets the layout test compares between the
// host compiler and the device compiler (tests/kernels/test_layout.cpp, tests/kernels/probes/layout.cl).
#ifndef TANDEM_SHARED_LAYOUT_PROBE_H
#define TANDEM_SHARED_LAYOUT_PROBE_H

#include "shared/bvh_layout.h"
#include "shared/cv.h"
#include "shared/optim.h"
#include "shared/reservoir.h"
#include "shared/scene_layout.h"

// X-macro lists: STRUCT(T) for each shared struct, FIELD(T, f) for each of its fields, in order.
// Add a struct here when you add it to kernels/shared.
// clang-format off
#define TANDEM_SHARED_LAYOUT(STRUCT, FIELD) \
    STRUCT(BvhNode) \
    FIELD(BvhNode, lmin) \
    FIELD(BvhNode, lmax) \
    FIELD(BvhNode, rmin) \
    FIELD(BvhNode, rmax) \
    STRUCT(Bvh4Node) \
    FIELD(Bvh4Node, min_x) \
    FIELD(Bvh4Node, min_y) \
    FIELD(Bvh4Node, min_z) \
    FIELD(Bvh4Node, max_x) \
    FIELD(Bvh4Node, max_y) \
    FIELD(Bvh4Node, max_z) \
    FIELD(Bvh4Node, child) \
    FIELD(Bvh4Node, count) \
    STRUCT(Bvh8Node) \
    FIELD(Bvh8Node, min_x) \
    FIELD(Bvh8Node, min_y) \
    FIELD(Bvh8Node, min_z) \
    FIELD(Bvh8Node, max_x) \
    FIELD(Bvh8Node, max_y) \
    FIELD(Bvh8Node, max_z) \
    FIELD(Bvh8Node, child) \
    FIELD(Bvh8Node, count) \
    STRUCT(BvhTriangle) \
    FIELD(BvhTriangle, v0) \
    FIELD(BvhTriangle, v1) \
    FIELD(BvhTriangle, v2) \
    FIELD(BvhTriangle, plane_n) \
    STRUCT(ShadingPrimitive) \
    FIELD(ShadingPrimitive, v0) \
    FIELD(ShadingPrimitive, v1) \
    FIELD(ShadingPrimitive, v2) \
    FIELD(ShadingPrimitive, n_front) \
    STRUCT(BvhTri4) \
    FIELD(BvhTri4, ax) \
    FIELD(BvhTri4, ay) \
    FIELD(BvhTri4, az) \
    FIELD(BvhTri4, bx) \
    FIELD(BvhTri4, by) \
    FIELD(BvhTri4, bz) \
    FIELD(BvhTri4, cx) \
    FIELD(BvhTri4, cy) \
    FIELD(BvhTri4, cz) \
    FIELD(BvhTri4, nx) \
    FIELD(BvhTri4, ny) \
    FIELD(BvhTri4, nz) \
    FIELD(BvhTri4, prim) \
    FIELD(BvhTri4, unused) \
    STRUCT(Ray) \
    FIELD(Ray, org) \
    FIELD(Ray, dir) \
    STRUCT(Hit) \
    FIELD(Hit, t) \
    FIELD(Hit, prim) \
    FIELD(Hit, u) \
    FIELD(Hit, v) \
    STRUCT(DeviceCamera) \
    FIELD(DeviceCamera, origin) \
    FIELD(DeviceCamera, dir_x) \
    FIELD(DeviceCamera, dir_y) \
    FIELD(DeviceCamera, dir_z) \
    FIELD(DeviceCamera, near_clip) \
    FIELD(DeviceCamera, far_clip) \
    FIELD(DeviceCamera, width) \
    FIELD(DeviceCamera, height) \
    FIELD(DeviceCamera, medium) \
    STRUCT(Material) \
    FIELD(Material, reflectance) \
    FIELD(Material, specular) \
    FIELD(Material, eta) \
    FIELD(Material, k) \
    FIELD(Material, type) \
    FIELD(Material, flags) \
    FIELD(Material, alpha) \
    FIELD(Material, texture) \
    FIELD(Material, reflectance_param) \
    FIELD(Material, specular_param) \
    FIELD(Material, alpha_param) \
    FIELD(Material, plastic_table) \
    STRUCT(TriangleInfo) \
    FIELD(TriangleInfo, material) \
    FIELD(TriangleInfo, emitter) \
    FIELD(TriangleInfo, interior) \
    FIELD(TriangleInfo, exterior) \
    STRUCT(DeviceGrid) \
    FIELD(DeviceGrid, to_local0) \
    FIELD(DeviceGrid, to_local1) \
    FIELD(DeviceGrid, to_local2) \
    FIELD(DeviceGrid, offset) \
    FIELD(DeviceGrid, nx) \
    FIELD(DeviceGrid, ny) \
    FIELD(DeviceGrid, nz) \
    FIELD(DeviceGrid, channels) \
    STRUCT(Medium) \
    FIELD(Medium, sigma_t) \
    FIELD(Medium, albedo) \
    FIELD(Medium, kind) \
    FIELD(Medium, phase) \
    FIELD(Medium, g) \
    FIELD(Medium, majorant) \
    FIELD(Medium, sigma_t_grid) \
    FIELD(Medium, albedo_grid) \
    FIELD(Medium, majorant_grid) \
    FIELD(Medium, sigma_t_param) \
    FIELD(Medium, albedo_param) \
    FIELD(Medium, scale_param) \
    FIELD(Medium, g_param) \
    STRUCT(EmissiveTriangle) \
    FIELD(EmissiveTriangle, p0) \
    FIELD(EmissiveTriangle, p1) \
    FIELD(EmissiveTriangle, p2) \
    FIELD(EmissiveTriangle, nx) \
    FIELD(EmissiveTriangle, ny) \
    FIELD(EmissiveTriangle, nz) \
    FIELD(EmissiveTriangle, radiance_param) \
    STRUCT(TriangleUV) \
    FIELD(TriangleUV, uv01) \
    FIELD(TriangleUV, uv2) \
    STRUCT(TriangleNormals) \
    FIELD(TriangleNormals, n0) \
    FIELD(TriangleNormals, n1) \
    FIELD(TriangleNormals, n2) \
    FIELD(TriangleNormals, link) \
    STRUCT(NormalJacobian) \
    FIELD(NormalJacobian, c0) \
    FIELD(NormalJacobian, c1) \
    FIELD(NormalJacobian, c2) \
    STRUCT(TextureInfo) \
    FIELD(TextureInfo, color0) \
    FIELD(TextureInfo, color1) \
    FIELD(TextureInfo, uv_row0) \
    FIELD(TextureInfo, uv_row1) \
    FIELD(TextureInfo, kind) \
    FIELD(TextureInfo, offset) \
    FIELD(TextureInfo, width) \
    FIELD(TextureInfo, height) \
    FIELD(TextureInfo, filter) \
    FIELD(TextureInfo, param) \
    STRUCT(DeltaLight) \
    FIELD(DeltaLight, position) \
    FIELD(DeltaLight, intensity) \
    FIELD(DeltaLight, axis) \
    FIELD(DeltaLight, cos_beam) \
    FIELD(DeltaLight, cutoff) \
    FIELD(DeltaLight, inv_transition) \
    FIELD(DeltaLight, type) \
    STRUCT(EnvMap) \
    FIELD(EnvMap, to_local0) \
    FIELD(EnvMap, to_local1) \
    FIELD(EnvMap, to_local2) \
    FIELD(EnvMap, width) \
    FIELD(EnvMap, height) \
    FIELD(EnvMap, texel_offset) \
    FIELD(EnvMap, cdf_offset) \
    FIELD(EnvMap, total) \
    STRUCT(AdamConfig) \
    FIELD(AdamConfig, beta1) \
    FIELD(AdamConfig, beta2) \
    FIELD(AdamConfig, epsilon) \
    FIELD(AdamConfig, correction1) \
    FIELD(AdamConfig, correction2) \
    STRUCT(CvState) \
    FIELD(CvState, estimate) \
    FIELD(CvState, alpha) \
    FIELD(CvState, var_cv) \
    FIELD(CvState, coef_h) \
    FIELD(CvState, coef_c) \
    FIELD(CvState, mean_h) \
    FIELD(CvState, mean_d) \
    FIELD(CvState, var_h) \
    FIELD(CvState, var_d) \
    FIELD(CvState, cov_hd) \
    STRUCT(CvConfig) \
    FIELD(CvConfig, beta1) \
    FIELD(CvConfig, beta2) \
    FIELD(CvConfig, variance) \
    FIELD(CvConfig, corr1_after) \
    FIELD(CvConfig, corr2) \
    FIELD(CvConfig, iteration) \
    FIELD(CvConfig, warmup) \
    FIELD(CvConfig, updates) \
    STRUCT(AliasEntry) \
    FIELD(AliasEntry, q) \
    FIELD(AliasEntry, alias) \
    STRUCT(RenderParams) \
    FIELD(RenderParams, env_param) \
    FIELD(RenderParams, seed) \
    FIELD(RenderParams, sample_begin) \
    FIELD(RenderParams, sample_count) \
    FIELD(RenderParams, max_depth) \
    FIELD(RenderParams, rr_depth) \
    FIELD(RenderParams, emissive_count) \
    FIELD(RenderParams, light_env_prob) \
    FIELD(RenderParams, delta_count) \
    STRUCT(Reservoir) \
    FIELD(Reservoir, light) \
    FIELD(Reservoir, u1) \
    FIELD(Reservoir, u2) \
    FIELD(Reservoir, W) \
    FIELD(Reservoir, prim) \
    FIELD(Reservoir, b1) \
    FIELD(Reservoir, b2) \
    FIELD(Reservoir, M) \
    STRUCT(RestirParams) \
    FIELD(RestirParams, seed) \
    FIELD(RestirParams, spp) \
    FIELD(RestirParams, candidates) \
    FIELD(RestirParams, temporal) \
    FIELD(RestirParams, spatial) \
    FIELD(RestirParams, radius) \
    FIELD(RestirParams, visibility) \
    FIELD(RestirParams, m_cap) \
    FIELD(RestirParams, normal_cos) \
    FIELD(RestirParams, depth_rel) \
    FIELD(RestirParams, radiance_floor) \
    FIELD(RestirParams, direct)
// clang-format on

#endif // TANDEM_SHARED_LAYOUT_PROBE_H
