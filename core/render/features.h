// The scheduler's first job: which kernel features a scene needs. The one mapping from a scene to
// build flags; kernels test each flag with #if, and every flag is always passed (0 or 1).
#pragma once

#include "core/render/policy.h"
#include "core/scene/render_scene.h"
#include "runtime/build_flags.h"
#include "runtime/context.h"
#include "runtime/device.h"

namespace tandem {

/// How next-event estimation and BSDF sampling combine. Tests compare the three; renders use MIS.
/// bsdf_only cannot see point and spot lights (no direction reaches them), so the comparison
/// holds for scenes without them.
enum class LightStrategy { mis = 0, bsdf_only = 1, nee_only = 2 };

/// The flags `scene` needs, those of the device policy (core/render/policy.h: decide_policy,
/// for the scene's film) among them:
///   BVH_WIDTH       2, 4 or 8: the BVH layout (`bvh_width` if given, else the policy's:
///                   Tuning::bvh_width, else preferred_bvh_width). Same bits.
///   BVH_AXIS_LOOPS  1 on CPUs: the triangle test's leaf loops copied per dominant axis; 0 on
///                   other devices (bvh_axis_loops; kernels/shared/bvh_traverse.h). Same bits.
///   BVH_ANALYTIC    1 if the scene has analytic spheres or disks (RenderScene::mesh): the leaf
///                   loops test their records, and the shading rebuilds their points (as the
///                   wavefront's vectorised stage does, with selects: wf_primitive_point)
///   BVH_TRI4        1 for a four- or eight-wide BVH of a scene without analytic shapes where
///                   the policy (preferred_leaf_format, or Tuning::bvh_tri4_leaves) takes leaves
///                   of BvhTri4 blocks, four triangles per float4 test (kernels/shared/bvh_tri4.h).
///                   Same bits.
///   BVH_PREFETCH    1 where the policy prefetches (prefers_prefetch: an eight-wide BVH of a
///                   large mesh on a CPU, or Tuning::bvh_prefetch): a node visit prefetches the
///                   children the ray enters, where the kernel compiler is Clang for x86 with AVX
///                   (kernels/shared/bvh8_traverse.h). Same bits.
///   CAMERA_PACKETS  1 for the eight-wide tree of blocks on a CPU (prefers_camera_packets, or
///                   Tuning::camera_packets): render_pass traces the camera rays of up to eight
///                   samples of a pixel as one packet (kernels/shared/bvh8_packet.h). Same bits.
///   HAS_AREA_LIGHTS 1 if any shape emits: emission lookups and triangle light sampling
///   HAS_ENV_LIGHT   1 if there is an environment (constant or envmap)
///   HAS_ENVMAP      1 if the environment is an importance-sampled envmap
///   ENVMAP_SEARCH_STEPS  with HAS_ENVMAP, ceil(log2) of the envmap's larger CDF (its rows of
///                   cells or its columns): the wavefront's unrolled binary searches; 0 without
///   HAS_TEXTURES    1 if any texture exists: uv interpolation and texture lookups
///   HAS_BITMAPS     1 if any texture is a bitmap: the wavefront's texel gathers (without, its
///                   texture lookup is the checkerboard's alone)
///   HAS_DELTA_LIGHTS 1 if there are point or spot lights
///   HAS_SHADING_NORMALS 1 if a mesh shape is shaded with vertex normals (core/scene/vertex_normals.h):
///                   the shading frame turns to the interpolated normal (interaction_shade), and
///                   the wavefront's vectorised stage leaves such hits to its general one
///   BSDF_CONDUCTOR  1 if a conductor or roughconductor is used; likewise BSDF_DIELECTRIC
///                   (dielectric) and BSDF_PLASTIC (roughplastic). Diffuse is always compiled.
///   HAS_MEDIA       1 if the scene has a participating medium or a null bsdf: every path is the
///                   volumetric one (kernels/path/media.h). The wavefront, the two-state path,
///                   the adjoint and ReSTIR do not cover media yet: their entry points refuse such
///                   scenes (require_no_media)
///   LIGHT_STRATEGY  0 MIS, 1 BSDF sampling only, 2 next-event estimation only
///   RESTIR          0 here: 1 compiles light-sample reuse into the adjoint (kernels/restir.cl,
///                   kernels/path/restir.h), which the caller sets when it resamples reservoirs
///   WAVEFRONT       1 for the scenes kernels/wavefront.cl covers (wavefront_supported) where the
///                   policy runs it (wavefront_faster: PoCL on an AVX-512 CPU, every material
///                   diffuse, a film large enough; or Tuning::wavefront): the passes run stage by
///                   stage so that PoCL vectorises the shading; 0 runs the megakernels. Same bits.
///                   Flags turned on afterwards (a BSDF, the environment) rule the wavefront out
///                   again: the passes use it where wavefront_supported(flags) holds (policy_of).
///   DET_MATH        1: sin, cos, acos and atan2 from kernels/shared/det_math.h, the same bits on
///                   every device; 0 (`tandem bench render` only, to measure the cost): the
///                   implementation's built-ins
///   SHADOW_RECORD   1: the PRB adjoint's primal pass records the outcome of each NEE shadow ray
///                   (one bit per vertex) and its replay reads them instead of tracing the rays
///                   again (kernels/path/record.h, PathRecord); 0 (Tuning::shadow_record, to
///                   measure what it saves): the replay traces them. Same bits.
///   SHAPE_GRAD      0 here: 1 compiles the interior term of shape gradients into the replay
///                   (kernels/path/shape_adjoint.h); DeviceScene::enable_shape_gradients sets it
///                   when a gradient first differentiates vertex positions
/// Programs are cached per flag set (the options are part of the binary cache key).
///
/// The policy is the one of `ctx` (its device and Tuning), for gradient work.
BuildFlags render_features(const RenderScene& scene, const Context& ctx,
                           LightStrategy strategy = LightStrategy::mis, int bvh_width = 0);
/// The same on `device` with `tuning`, for `work`.
BuildFlags render_features(const RenderScene& scene, const DeviceInfo& device,
                           const Tuning& tuning, LightStrategy strategy = LightStrategy::mis,
                           int bvh_width = 0, Workload work = Workload::gradient);
/// The same with the device's own policy: a Tuning that forces nothing.
BuildFlags render_features(const RenderScene& scene, const DeviceInfo& device,
                           LightStrategy strategy = LightStrategy::mis, int bvh_width = 0);

/// render_features for a forward render alone (`tandem render`, `tandem bench render`): the BVH
/// is forward_bvh_width's unless the Tuning says otherwise. Gradient and two-state work keeps
/// render_features' layout.
BuildFlags forward_render_features(const RenderScene& scene, const Context& ctx);
/// The same on `device` with `tuning` (default: one that forces nothing).
BuildFlags forward_render_features(const RenderScene& scene, const DeviceInfo& device,
                                   const Tuning& tuning = Tuning{});

/// The flags that only say what `scene` contains (not how to render it): HAS_*, ENVMAP_*,
/// BVH_ANALYTIC and BSDF_*.
BuildFlags content_features(const RenderScene& scene);

/// Checks that `features` can render `scene`: every feature the scene needs is on (more may be;
/// HAS_ENVMAP and ENVMAP_SEARCH_STEPS must match exactly, as they change what the environment is
/// and how it is searched). Throws Error naming the
/// first missing flag.
void check_features(const RenderScene& scene, const BuildFlags& features);

} // namespace tandem
