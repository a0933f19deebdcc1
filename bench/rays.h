// Test and benchmark ray sets over a mesh's bounds: coherent (pinhole camera), incoherent (random
// origins and directions) and shadow segments. Deterministic: counter-based RNG keyed by `seed`.
#pragma once

#include <cstdint>
#include <vector>

#include "core/scene/mesh.h"
#include "shared/bvh_layout.h"

namespace tandem {

/// width x height primary rays of a pinhole camera outside the bounds, looking at their center
/// from the (+1, +0.6, +0.8) direction, with a field of view that frames the bounding sphere.
/// Rays are in scanline order; tmin = 0, tmax = +inf.
std::vector<gpu::Ray> make_camera_rays(const Bounds& bounds, int width, int height);

/// `count` rays with origins uniform in the bounds (grown by 10%) and directions uniform on the
/// sphere; tmin = 0, tmax = +inf.
std::vector<gpu::Ray> make_random_rays(const Bounds& bounds, std::size_t count, std::uint32_t seed);

/// `count` shadow segments between two uniform points in the bounds: dir = p1 - p0, t in [0, 1).
std::vector<gpu::Ray> make_shadow_rays(const Bounds& bounds, std::size_t count, std::uint32_t seed);

} // namespace tandem
