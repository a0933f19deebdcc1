// The secondary boundary term's lights (core/render/boundary.h). The bounds by which its direction
// density skips emissive triangles (emissive_chunks; kernels/shared/boundary.h:
// emissive_chunk_near): no triangle that a ray crosses is ever skipped, and most chunks a ray does
// not come near are. The light pairs (secondary_light_pairs): which edges pair with which lights,
// at what pmf, against cases worked out by hand.
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

/// The groups of emissive_chunks' buffer (after its n chunks): (sphere, first chunk, end chunk).
struct Group {
    gpu::float4 sphere;
    std::uint32_t first, end;
};
std::vector<Group> groups_of(const std::vector<gpu::float4>& chunks, std::size_t n) {
    std::vector<Group> out;
    for (std::size_t k = n; k + 1 < chunks.size(); k += 2) {
        out.push_back({chunks[k], std::uint32_t(chunks[k + 1].x), std::uint32_t(chunks[k + 1].y)});
    }
    return out;
}

TEST_CASE("emissive chunks: every corner of a chunk's or group's triangles lies inside its sphere") {
    const std::vector<gpu::EmissiveTriangle> emissive = many_lights();
    REQUIRE(emissive.size() > 1000);
    const std::vector<gpu::float4> chunks = emissive_chunks(emissive);
    const std::size_t n = (emissive.size() + EMISSIVE_CHUNK - 1) / EMISSIVE_CHUNK;
    const std::vector<Group> groups = groups_of(chunks, n);
    // the groups tile the chunks in order, each of at most EMISSIVE_GROUP, none over two lights
    REQUIRE(chunks.size() == n + 2 * groups.size());
    std::uint32_t next = 0;
    double widest = 0.0, widest_group = 0.0;
    for (const Group& g : groups) {
        CHECK(g.first == next);
        CHECK(g.end > g.first);
        CHECK(g.end - g.first <= EMISSIVE_GROUP);
        next = g.end;
        for (std::size_t e = g.first * EMISSIVE_CHUNK;
             e < std::min<std::size_t>(g.end * EMISSIVE_CHUNK, emissive.size()); ++e) {
            const gpu::float4& b = chunks[e / EMISSIVE_CHUNK];
            for (const gpu::float4& p : {emissive[e].p0, emissive[e].p1, emissive[e].p2}) {
                CHECK(glm::length(glm::dvec3(v3(p)) - glm::dvec3(v3(b))) <= double(b.w));
                CHECK(glm::length(glm::dvec3(v3(p)) - glm::dvec3(v3(g.sphere))) <=
                      double(g.sphere.w));
            }
            widest = std::max(widest, double(b.w));
        }
        widest_group = std::max(widest_group, double(g.sphere.w));
    }
    CHECK(next == n);
    CHECK(groups.size() == 48); // one light's 124 chunks: four groups
    // tight: a chunk of a sphere light of radius 0.1 is smaller than the light, a group no larger
    // (one light: the lights lie 2 or more apart)
    CHECK(widest < 0.1);
    CHECK(widest_group < 0.11);
    CHECK(emissive_chunks({}).size() == 1); // never an empty buffer
}

TEST_CASE("emissive chunks: a ray that crosses a triangle is near its chunk and group, most others are not") {
    const std::vector<gpu::EmissiveTriangle> emissive = many_lights();
    const std::vector<gpu::float4> chunks = emissive_chunks(emissive);
    const std::size_t n = (emissive.size() + EMISSIVE_CHUNK - 1) / EMISSIVE_CHUNK;
    const std::vector<Group> groups = groups_of(chunks, n);
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
        for (const Group& g : groups)
            if (e >= g.first * EMISSIVE_CHUNK && e < g.end * EMISSIVE_CHUNK)
                CHECK(gpu::emissive_chunk_near(og, wg, g.sphere) == 1);
        // a chunk half the table away: another light's (each light's 3968 triangles fill 124)
        const std::size_t other = (e / EMISSIVE_CHUNK + n / 2) % n;
        near_other += gpu::emissive_chunk_near(og, wg, chunks[other]);
        ++others;
    }
    // a ray aimed at one light rarely passes near another
    CHECK(near_other < others / 50);
}

TEST_CASE("emissive chunks: the delta lights' share is one less the triangles'") {
    // no point or spot light on the many-lights scene: nothing left but rounding
    CHECK(std::fabs(delta_light_share(many_lights())) < 1e-4);
    // two triangles of 0.25 beside point lights of 0.5: 0.5 left, exactly
    gpu::EmissiveTriangle t{};
    t.p1.w = 0.25f;
    CHECK(delta_light_share({t, t}) == 0.5f);
}

namespace {

/// A small emissive triangle about p (side 0.1, facing -z) of radiance parameter `param` and
/// selection pmf `pmf`.
gpu::EmissiveTriangle light_at(glm::vec3 p, unsigned param, float pmf) {
    gpu::EmissiveTriangle t{};
    t.p0 = gpu::make_float4(p.x - 0.05f, p.y - 0.05f, p.z, 0.005f);
    t.p1 = gpu::make_float4(p.x + 0.05f, p.y - 0.05f, p.z, pmf);
    t.p2 = gpu::make_float4(p.x, p.y + 0.05f, p.z, 0.0f);
    t.nz = -1.0f;
    t.radiance_param = param;
    return t;
}

/// An edge from a to b between faces of outward normals n0 and n1 (n1 zero: a border), length
/// pmf left as secondary_edges() leaves it (unused here).
gpu::SecondaryEdge edge(glm::vec3 a, glm::vec3 b, glm::vec3 n0, glm::vec3 n1) {
    gpu::SecondaryEdge e{};
    e.p0 = gpu::make_float4(a.x, a.y, a.z, 0.0f);
    e.p1 = gpu::make_float4(b.x, b.y, b.z, 0.0f);
    e.n0 = gpu::make_float4(n0.x, n0.y, n0.z, 0.5f);
    const bool border = n1 == glm::vec3(0.0f);
    e.n1 = gpu::make_float4(n1.x, n1.y, n1.z, border ? 0.0f : 1.0f);
    return e;
}

} // namespace

TEST_CASE("light pairs: an edge pairs with the lights it is a silhouette against, borders with all") {
    // a convex corner along z whose faces look along +x and +y
    const glm::vec3 nx(1, 0, 0), ny(0, 1, 0);
    const std::vector<gpu::SecondaryEdge> edges{
        edge({0, 0, 0}, {0, 0, 1}, nx, ny),         // 0: the corner
        edge({0, 0, 0}, {0, 0, 2}, nx, ny),         // 1: the same, twice as long
        edge({3, 0, 0}, {3, 0, 1}, nx, {0, 0, 0})}; // 2: a border
    // light 0 (param 10): beyond the +x face only, so both corners are silhouettes against it;
    // light 1 (param 20; two triangles): in front of both faces, neither is
    const std::vector<gpu::EmissiveTriangle> emissive{light_at({5, -5, 0.5f}, 10, 0.5f),
                                                      light_at({5, 5, 0.5f}, 20, 0.25f),
                                                      light_at({5, 5.1f, 0.5f}, 20, 0.25f)};
    const SecondaryPairList p = secondary_light_pairs(edges, emissive);
    REQUIRE(p.lights.size() == 2);
    CHECK(p.lights[0].x == 0);
    CHECK(p.lights[0].y == 1);
    CHECK(p.lights[1].x == 1);
    CHECK(p.lights[1].y == 2);
    // (0, 0), (1, 0), (2, 0), (2, 1), in that order
    REQUIRE(p.list.size() == 4);
    CHECK((p.list[0].x == 0 && p.list[0].y == 0));
    CHECK((p.list[1].x == 1 && p.list[1].y == 0));
    CHECK((p.list[2].x == 2 && p.list[2].y == 0));
    CHECK((p.list[3].x == 2 && p.list[3].y == 1));
    REQUIRE(p.first.size() == edges.size() + 1);
    CHECK(p.first[0] == 0);
    CHECK(p.first[1] == 1);
    CHECK(p.first[2] == 2);
    CHECK(p.first[3] == 4);
    double sum = 0.0;
    for (float q : p.pmf) sum += q;
    CHECK(sum == doctest::Approx(1.0).epsilon(1e-6));
    // length over squared distance times power: the long corner is a little nearer the light than
    // twice the short one's share would be (its middle at z 1, the light at z 0.5)
    const double d0 = glm::length(glm::dvec3(5, -5, 0.5) - glm::dvec3(0, 0, 0.5));
    const double d1 = glm::length(glm::dvec3(5, -5, 0.5) - glm::dvec3(0, 0, 1.0));
    CHECK(p.pmf[1] / p.pmf[0] == doctest::Approx(2.0 * d0 * d0 / (d1 * d1)).epsilon(1e-5));
    // the border's two pairs: power 0.5 against 0.5, each over its squared distance
    const double b0 = glm::length(glm::dvec3(5, -5, 0.5) - glm::dvec3(3, 0, 0.5));
    const double b1 = glm::length(glm::dvec3(5, 5.05, 0.5) - glm::dvec3(3, 0, 0.5));
    CHECK(p.pmf[3] / p.pmf[2] == doctest::Approx(b0 * b0 / (b1 * b1)).epsilon(1e-5));
}

TEST_CASE("light pairs: none without two lights of some power, or without edges") {
    const std::vector<gpu::SecondaryEdge> edges{edge({0, 0, 0}, {0, 0, 1}, {1, 0, 0}, {0, 1, 0})};
    const gpu::EmissiveTriangle a = light_at({5, -5, 0.5f}, 1, 0.5f),
                                b = light_at({-5, 5, 0.5f}, 2, 0.5f);
    CHECK(secondary_light_pairs(edges, {a, b}).list.size() == 2); // a corner between them
    CHECK(secondary_light_pairs(edges, {}).list.empty());
    CHECK(secondary_light_pairs(edges, {a}).list.empty());
    gpu::EmissiveTriangle black = b;
    black.p1.w = 0.0f; // a light of no power
    CHECK(secondary_light_pairs(edges, {a, black}).list.empty());
    CHECK(secondary_light_pairs({}, {a, b}).list.empty());
}
