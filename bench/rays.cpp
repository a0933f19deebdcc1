// Ray set generation for tests and benchmarks.
#include "bench/rays.h"

#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "shared/rng.h"

namespace tandem {

namespace {

constexpr float k_inf = std::numeric_limits<float>::infinity();

gpu::Ray make_ray(const glm::vec3& o, const glm::vec3& d, float tmin, float tmax) {
    return gpu::Ray{gpu::make_float4(o.x, o.y, o.z, tmin), gpu::make_float4(d.x, d.y, d.z, tmax)};
}

glm::vec3 uniform_in(const Bounds& b, std::uint32_t seed, std::uint32_t i, std::uint32_t dim0) {
    const glm::vec3 u(gpu::rng_uniform(seed, i, 0, dim0), gpu::rng_uniform(seed, i, 0, dim0 + 1),
                      gpu::rng_uniform(seed, i, 0, dim0 + 2));
    return b.lo + u * (b.hi - b.lo);
}

Bounds grown(const Bounds& b, float fraction) {
    const glm::vec3 pad = 0.5f * fraction * b.extent();
    return Bounds{b.lo - pad, b.hi + pad};
}

} // namespace

std::vector<gpu::Ray> make_camera_rays(const Bounds& bounds, int width, int height) {
    const glm::vec3 center = bounds.center();
    const float radius = 0.5f * glm::length(bounds.extent());
    const glm::vec3 forward = -glm::normalize(glm::vec3(1.0f, 0.6f, 0.8f));
    const glm::vec3 eye = center - forward * (2.5f * radius);
    const glm::vec3 right = glm::normalize(glm::cross(forward, glm::vec3(0.0f, 0.0f, 1.0f)));
    const glm::vec3 up = glm::cross(right, forward);
    const float half = std::tan(std::asin(1.0f / 2.5f)); // half-angle that frames the sphere
    const float aspect = static_cast<float>(width) / static_cast<float>(height);
    std::vector<gpu::Ray> rays;
    rays.reserve(static_cast<std::size_t>(width) * height);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const float sx = (2.0f * (x + 0.5f) / width - 1.0f) * half * aspect;
            const float sy = (1.0f - 2.0f * (y + 0.5f) / height) * half;
            rays.push_back(make_ray(eye, glm::normalize(forward + sx * right + sy * up), 0.0f, k_inf));
        }
    return rays;
}

std::vector<gpu::Ray> make_random_rays(const Bounds& bounds, std::size_t count, std::uint32_t seed) {
    const Bounds box = grown(bounds, 0.1f);
    std::vector<gpu::Ray> rays(count);
    for (std::size_t i = 0; i < count; ++i) {
        const auto id = static_cast<std::uint32_t>(i);
        const glm::vec3 o = uniform_in(box, seed, id, 0);
        const float z = 1.0f - 2.0f * gpu::rng_uniform(seed, id, 0, 3);
        const float phi = 6.2831853f * gpu::rng_uniform(seed, id, 0, 4);
        const float r = std::sqrt(std::fmax(0.0f, 1.0f - z * z));
        rays[i] = make_ray(o, glm::vec3(r * std::cos(phi), r * std::sin(phi), z), 0.0f, k_inf);
    }
    return rays;
}

std::vector<gpu::Ray> make_shadow_rays(const Bounds& bounds, std::size_t count, std::uint32_t seed) {
    std::vector<gpu::Ray> rays(count);
    for (std::size_t i = 0; i < count; ++i) {
        const auto id = static_cast<std::uint32_t>(i);
        const glm::vec3 p0 = uniform_in(bounds, seed, id, 0), p1 = uniform_in(bounds, seed, id, 3);
        rays[i] = make_ray(p0, p1 - p0, 0.0f, 1.0f);
    }
    return rays;
}

} // namespace tandem
