// The bounds by which the secondary boundary term's direction density skips emissive triangles
// (core/render/boundary.h: emissive_chunks; kernels/shared/boundary.h: emissive_chunk_near): no
// triangle that a ray crosses is ever skipped, and most chunks a ray does not come near are.
#include <doctest/doctest.h>

#include <cmath>
#include <random>

#include <glm/geometric.hpp>

#include "core/render/boundary.h"
#include "core/scene/scene.h"

using namespace tandem;

namespace {

glm::vec3 v3(const gpu::float4& p) { return {p.x, p.y, p.z}; }

/// The twelve sphere lights (64 x 32 quads each) of the bundled many-lights scene.
std::vector<gpu::EmissiveTriangle> many_lights() {
    const RenderScene rs = build_render_scene(
        load_scene(std::string(TANDEM_SOURCE_DIR) + "/scenes/shadow-lights.xml", {{"res", "8"}}));
    return rs.emissive;
}

} // namespace

TEST_CASE("emissive chunks: every corner of a chunk's triangles lies inside its sphere") {
    const std::vector<gpu::EmissiveTriangle> emissive = many_lights();
    REQUIRE(emissive.size() > 1000);
    const std::vector<gpu::float4> chunks = emissive_chunks(emissive);
    CHECK(chunks.size() == (emissive.size() + EMISSIVE_CHUNK - 1) / EMISSIVE_CHUNK);
    double widest = 0.0;
    for (std::size_t e = 0; e < emissive.size(); ++e) {
        const gpu::float4& b = chunks[e / EMISSIVE_CHUNK];
        for (const gpu::float4& p : {emissive[e].p0, emissive[e].p1, emissive[e].p2}) {
            const double d = glm::length(glm::dvec3(v3(p)) - glm::dvec3(v3(b)));
            CHECK(d <= double(b.w));
        }
        widest = std::max(widest, double(b.w));
    }
    // tight: a chunk of a sphere light of radius 0.1 is smaller than the light
    CHECK(widest < 0.1);
    CHECK(emissive_chunks({}).size() == 1); // never an empty buffer
}

TEST_CASE("emissive chunks: a ray that crosses a triangle is near its chunk; most others are not") {
    const std::vector<gpu::EmissiveTriangle> emissive = many_lights();
    const std::vector<gpu::float4> chunks = emissive_chunks(emissive);
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    int near_other = 0, others = 0;
    for (int k = 0; k < 20000; ++k) {
        // from a point of the scene's extent toward a random point of a random triangle
        const glm::vec3 o(8.0f * u(rng) - 4.0f, 6.0f * u(rng) - 2.0f, 8.0f * u(rng) - 4.0f);
        const std::size_t e = std::min(emissive.size() - 1, std::size_t(u(rng) * emissive.size()));
        float b1 = u(rng), b2 = u(rng);
        if (b1 + b2 > 1.0f) b1 = 1.0f - b1, b2 = 1.0f - b2;
        const gpu::EmissiveTriangle& t = emissive[e];
        const glm::vec3 p = v3(t.p0) + b1 * (v3(t.p1) - v3(t.p0)) + b2 * (v3(t.p2) - v3(t.p0));
        const glm::vec3 w = glm::normalize(p - o);
        const gpu::float3 og = gpu::make_float3(o.x, o.y, o.z), wg = gpu::make_float3(w.x, w.y, w.z);
        CHECK(gpu::emissive_chunk_near(og, wg, chunks[e / EMISSIVE_CHUNK]) == 1);
        // a chunk half the table away: another light's (each light's 4096 triangles fill 128)
        const std::size_t other = (e / EMISSIVE_CHUNK + chunks.size() / 2) % chunks.size();
        near_other += gpu::emissive_chunk_near(og, wg, chunks[other]);
        ++others;
    }
    // a ray aimed at one light rarely passes near another
    CHECK(near_other < others / 50);
}

TEST_CASE("emissive chunks: the delta lights' share is one less the triangles' in table order") {
    const std::vector<gpu::EmissiveTriangle> emissive = many_lights();
    float p = 1.0f;
    double sum = 0.0;
    for (const gpu::EmissiveTriangle& t : emissive) {
        p -= t.p1.w;
        sum += t.p1.w;
    }
    CHECK(delta_light_share(emissive) == p); // the same float steps as the kernels took
    CHECK(std::fabs(delta_light_share(emissive)) < 1e-4); // no point or spot light there
    CHECK(sum == doctest::Approx(1.0).epsilon(1e-6));
}
