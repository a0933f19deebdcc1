// The device policy: the device's rules, and the Tuning's forced choices over them.
#include "core/render/policy.h"

#include "core/render/wavefront.h"
#include "runtime/pocl_llvm.h"

namespace tandem {

int bvh_axis_loops(const DeviceInfo& device) { return device.type == "CPU" ? 1 : 0; }

int preferred_bvh_width(const DeviceInfo& device) {
    if (device.type != "CPU") return 2;
    return device.native_float_width >= 8 ? 8 : 4;
}

int forward_bvh_width(const DeviceInfo& device, bool analytic) {
    if (device.type == "CPU") return preferred_bvh_width(device);
    return analytic ? 2 : 8;
}

LeafFormat preferred_leaf_format(const DeviceInfo& device, std::size_t triangles, int width) {
    if (device.type != "CPU" || width == 2) return LeafFormat::records;
    return width == 8 || triangles >= k_tri4_min_triangles ? LeafFormat::tri4 : LeafFormat::records;
}

bool prefers_prefetch(const DeviceInfo& device, std::size_t triangles, int width) {
    return device.type == "CPU" && width == 8 && triangles >= k_prefetch_min_triangles;
}

bool prefers_camera_packets(const DeviceInfo& device, int width, bool tri4) {
    return device.type == "CPU" && width == 8 && tri4;
}

bool wavefront_faster(const BuildFlags& f, const DeviceInfo& device, std::size_t pixels) {
    return pocl_widens_gathers(device) && f.get("BSDF_CONDUCTOR") == 0 &&
           f.get("BSDF_DIELECTRIC") == 0 && f.get("BSDF_PLASTIC") == 0 &&
           pixels >= k_wavefront_min_pixels;
}

namespace {

/// The bounces whose hits the adjoint records for its replay: none for scenes with media, whose
/// replay traces every ray again (kernels/path/volume.h: path_volume_from keeps no record).
unsigned record_bounces(const BuildFlags& content, const Tuning& tuning) {
    return content.get("HAS_MEDIA") == 1 ? 0u : tuning.hit_record_bounces;
}

} // namespace

DevicePolicy decide_policy(const BuildFlags& content, std::size_t triangles, std::size_t pixels,
                           const DeviceInfo& device, const Tuning& tuning, Workload work,
                           int bvh_width) {
    DevicePolicy p;
    const bool analytic = content.get("BVH_ANALYTIC") == 1;
    if (bvh_width)
        p.bvh_width = bvh_width;
    else if (tuning.bvh_width)
        p.bvh_width = tuning.bvh_width;
    else
        p.bvh_width = work == Workload::forward ? forward_bvh_width(device, analytic)
                                                : preferred_bvh_width(device);
    p.axis_loops = bvh_axis_loops(device) == 1;
    const bool tri4 = tuning.bvh_tri4_leaves
                          ? *tuning.bvh_tri4_leaves
                          : preferred_leaf_format(device, triangles, p.bvh_width) == LeafFormat::tri4;
    p.tri4_leaves = p.bvh_width != 2 && !analytic && tri4;
    // a forced prefetch holds for any tree (the kernels ignore it where there is nothing to do)
    p.prefetch = tuning.bvh_prefetch ? *tuning.bvh_prefetch
                                     : prefers_prefetch(device, triangles, p.bvh_width);
    // forced or not, the packets need the eight-wide tree of blocks
    p.camera_packets =
        (tuning.camera_packets ? *tuning.camera_packets : device.type == "CPU") &&
        p.bvh_width == 8 && p.tri4_leaves;
    p.repack = tuning.bvh_repack;
    const bool want = tuning.wavefront ? *tuning.wavefront : wavefront_faster(content, device, pixels);
    p.wavefront = want && wavefront_supported(content);
    p.shadow_record = tuning.shadow_record;
    p.hit_record_bounces = record_bounces(content, tuning);
    if (tuning.wavefront_record_bounces) p.wavefront_record_bounces = *tuning.wavefront_record_bounces;
    return p;
}

void set_policy_flags(const DevicePolicy& p, BuildFlags& f) {
    f.set("BVH_WIDTH", p.bvh_width);
    f.set("BVH_AXIS_LOOPS", p.axis_loops ? 1 : 0);
    f.set("BVH_TRI4", p.tri4_leaves ? 1 : 0);
    f.set("BVH_PREFETCH", p.prefetch ? 1 : 0);
    f.set("CAMERA_PACKETS", p.camera_packets ? 1 : 0);
    f.set("WAVEFRONT", p.wavefront ? 1 : 0);
    f.set("SHADOW_RECORD", p.shadow_record ? 1 : 0);
}

DevicePolicy policy_of(const BuildFlags& f, const Tuning& tuning) {
    DevicePolicy p;
    p.bvh_width = f.get("BVH_WIDTH");
    p.tri4_leaves = f.get("BVH_TRI4") == 1;
    p.axis_loops = f.get("BVH_AXIS_LOOPS") == 1;
    p.prefetch = f.get("BVH_PREFETCH") == 1;
    p.camera_packets = f.get("CAMERA_PACKETS") == 1;
    p.wavefront = f.get("WAVEFRONT") == 1 && wavefront_supported(f);
    p.shadow_record = f.get("SHADOW_RECORD") == 1;
    p.repack = tuning.bvh_repack;
    p.hit_record_bounces = record_bounces(f, tuning);
    if (tuning.wavefront_record_bounces) p.wavefront_record_bounces = *tuning.wavefront_record_bounces;
    return p;
}

} // namespace tandem
