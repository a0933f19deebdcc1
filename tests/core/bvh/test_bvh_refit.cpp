// Refitting a BVH to moved vertices (core/bvh/bvh_refit.h): the tree it keeps is valid, and
// traces what a tree built there traces, bit for bit; its SAH cost tracks how far it drifted.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "bench/rays.h"
#include "core/bvh/bvh_refit.h"
#include "host_trace.h"
#include "support.h"

using namespace tandem;
using test::host_any;
using test::host_closest;
using test::mesh_path;
using test::same_bytes;

namespace {

/// The knot with its vertices pushed along a smooth field of amplitude `a` (a shape a few
/// optimization steps might reach: neighbours move together).
TriangleMesh warped(TriangleMesh mesh, float a) {
    for (glm::vec3& p : mesh.positions)
        p += a * glm::vec3(std::sin(3.0f * p.y), std::cos(2.0f * p.z), std::sin(2.5f * p.x));
    return mesh;
}

/// The same vertices, each swapped with one far along the list: the triangles stretch across
/// the mesh, the worst a refit tree can be asked to hold.
TriangleMesh scrambled(TriangleMesh mesh) {
    const std::size_t n = mesh.positions.size();
    for (std::size_t i = 0; i < n / 2; i += 7) std::swap(mesh.positions[i], mesh.positions[n - 1 - i]);
    return mesh;
}

const int k_layouts[] = {2, 4, 5, 8, 9}; // 5, 9: four- and eight-wide with blocks of four

FlatBvh build(const TriangleMesh& mesh, int layout) {
    static EmbreeDevice device;
    return build_bvh(device, mesh, layout & ~1, layout % 2 ? LeafFormat::tri4 : LeafFormat::records);
}

} // namespace

TEST_SUITE("bvh") {
    TEST_CASE("refit: the mesh a tree was built from leaves it as it was, byte for byte") {
        const TriangleMesh mesh = load_mesh(mesh_path("knot_small.obj"));
        for (int layout : k_layouts) {
            INFO("layout " << layout);
            const FlatBvh built = build(mesh, layout);
            FlatBvh refit = built;
            refit_bvh(refit, mesh);
            CHECK(same_bytes(refit.nodes, built.nodes));
            CHECK(same_bytes(refit.nodes4, built.nodes4));
            CHECK(same_bytes(refit.nodes8, built.nodes8));
            CHECK(same_bytes(refit.triangles, built.triangles));
            CHECK(bvh_sah_cost(refit) == bvh_sah_cost(built));
        }
    }

    TEST_CASE("refit: moved vertices give a valid tree that finds the hits a new build finds") {
        const TriangleMesh mesh = load_mesh(mesh_path("knot_small.obj"));
        for (const TriangleMesh& moved : {warped(mesh, 0.05f), scrambled(mesh)}) {
            const std::vector<gpu::Ray> rays = make_random_rays(moved.bounds(), 4000, 5);
            for (int layout : k_layouts) {
                INFO("layout " << layout << ", " << (&moved == &mesh ? "" : "moved"));
                FlatBvh refit = build(mesh, layout);
                refit_bvh(refit, moved);
                REQUIRE_NOTHROW(check_bvh(refit, moved.triangle_count()));
                const FlatBvh rebuilt = build(moved, layout);
                // the closest hit does not depend on the tree (bvh_layout.h: the tie rule)
                int hits = 0, differ = 0;
                for (const gpu::Ray& ray : rays) {
                    const gpu::Hit a = host_closest(refit, ray), b = host_closest(rebuilt, ray);
                    differ += std::memcmp(&a, &b, sizeof a) != 0;
                    differ += host_any(refit, ray) != host_any(rebuilt, ray);
                    hits += b.prim != HIT_NONE;
                }
                CHECK(differ == 0);
                CHECK(hits > 400);
            }
        }
    }

    TEST_CASE("refit: the SAH cost over a new build's grows with the drift") {
        const TriangleMesh mesh = load_mesh(mesh_path("knot_small.obj"));
        for (int layout : k_layouts) {
            const FlatBvh built = build(mesh, layout);
            CHECK(bvh_sah_cost(built) > 1.0); // at least the root's children and one primitive
            // smooth drifts of growing amplitude, then the scramble: each costs more than a
            // build over the same vertices, and the scramble most
            double previous = 1.0, largest = 0.0;
            for (float a : {0.05f, 0.2f, 0.8f, -1.0f}) { // -1: scrambled
                const TriangleMesh moved = a < 0.0f ? scrambled(mesh) : warped(mesh, a);
                FlatBvh refit = built;
                refit_bvh(refit, moved);
                const double ratio = bvh_sah_cost(refit) / bvh_sah_cost(build(moved, layout));
                INFO("layout " << layout << ", amplitude " << a << ": " << ratio);
                CHECK(ratio > 1.0);
                if (a < 0.5f) CHECK(ratio > previous); // the two small drifts, in order
                if (a < 0.0f) CHECK(ratio > largest);
                previous = ratio, largest = std::max(largest, ratio);
            }
        }
    }
}
