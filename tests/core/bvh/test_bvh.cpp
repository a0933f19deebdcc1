// BVH build and flattening: structure, determinism, and the shared traversal against brute force.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <utility>

#include <glm/geometric.hpp>

#include "core/bvh/bvh_build.h"
#include "bench/rays.h"
#include "bench/tracer.h"
#include "core/render/policy.h"
#include "runtime/error.h"
#include "shared/sampling.h"
#include "host_trace.h"
#include "support.h"

using namespace tandem;
using test::mesh_path;

namespace {

/// A device described by its type alone ("CPU" or "GPU"), for the layout rules.
DeviceInfo device_of_type(const char* type) {
    DeviceInfo d;
    d.type = type;
    d.native_float_width = 8;
    return d;
}

/// The policy for a mesh of `triangles` triangles (no analytic shapes, an area light) with a
/// `width`-wide tree on `device`.
DevicePolicy policy_for(const DeviceInfo& device, std::size_t triangles, int width,
                        const Tuning& tuning) {
    BuildFlags content;
    content.set("BVH_ANALYTIC", 0).set("HAS_AREA_LIGHTS", 1).set("LIGHT_STRATEGY", 0);
    return decide_policy(content, triangles, 64 * 64, device, tuning, Workload::gradient, width);
}

using test::same_bytes;
using test::host_any;
using test::host_closest;

/// The closest hit by testing every triangle with the leaf routine (same test, same tie rule).
gpu::Hit brute_force(const FlatBvh& bvh, const gpu::Ray& ray) {
    const gpu::RayPre r = gpu::bvh_ray_prepare(ray);
    gpu::Hit best = gpu::bvh_miss(r.tmax);
    gpu::bvh_leaf_closest(&r, bvh.triangles.data(), 0, static_cast<unsigned>(bvh.triangles.size()),
                          &best);
    return best;
}

gpu::Ray make_ray(glm::vec3 o, glm::vec3 d, float tmax = INFINITY) {
    return gpu::Ray{gpu::make_float4(o.x, o.y, o.z, 0.0f), gpu::make_float4(d.x, d.y, d.z, tmax)};
}

/// The nearest root of |o + t d - c| = r in [tmin, tmax], in double precision; -1 if none.
double sphere_root(const gpu::Ray& ray, const Sphere& s) {
    const glm::dvec3 o(ray.org.x, ray.org.y, ray.org.z), d(ray.dir.x, ray.dir.y, ray.dir.z);
    const glm::dvec3 f = o - glm::dvec3(s.center);
    const double a = glm::dot(d, d), b = glm::dot(f, d), c = glm::dot(f, f) - double(s.radius) * s.radius;
    const double disc = b * b - a * c;
    if (disc < 0.0) return -1.0;
    for (double t : {(-b - std::sqrt(disc)) / a, (-b + std::sqrt(disc)) / a})
        if (t >= ray.org.w && t <= ray.dir.w) return t;
    return -1.0;
}

/// Where the ray meets the disk's plane within [tmin, tmax] and inside the disk, in double
/// precision, with the local (x, y) there; t = -1 if nowhere.
double disk_root(const gpu::Ray& ray, const Disk& disk, glm::dvec2* local) {
    const glm::dvec3 o(ray.org.x, ray.org.y, ray.org.z), d(ray.dir.x, ray.dir.y, ray.dir.z);
    const glm::dvec3 ax(disk.x_axis), ay(disk.y_axis), n = glm::cross(ax, ay);
    const double t = glm::dot(glm::dvec3(disk.center) - o, n) / glm::dot(d, n);
    if (!(t >= ray.org.w && t <= ray.dir.w)) return -1.0;
    const glm::dvec3 p = o + t * d - glm::dvec3(disk.center);
    *local = glm::dvec2(glm::dot(p, ax), glm::dot(p, ay)) / glm::dot(ax, ax);
    return glm::dot(*local, *local) <= 1.0 ? t : -1.0;
}


/// The primitive ids of every leaf of a BVH of any width and leaf format, with the leaf's box.
struct LeafContents {
    glm::vec3 lo, hi;
    std::vector<unsigned> prims;
};
std::vector<LeafContents> leaves_of(const FlatBvh& bvh) {
    std::vector<LeafContents> out;
    auto add = [&](float lx, float ly, float lz, float hx, float hy, float hz, unsigned first,
                   unsigned count) {
        if (count == 0) return;
        LeafContents leaf{{lx, ly, lz}, {hx, hy, hz}, {}};
        for (unsigned i = 0; i < count; ++i)
            leaf.prims.push_back(gpu::as_uint(leaf_record(bvh, first, i).v0.w));
        out.push_back(std::move(leaf));
    };
    for (const gpu::BvhNode& n : bvh.nodes) {
        add(n.lmin.x, n.lmin.y, n.lmin.z, n.lmax.x, n.lmax.y, n.lmax.z, gpu::as_uint(n.lmin.w),
            gpu::as_uint(n.lmax.w));
        const bool linked_twice = gpu::as_uint(n.rmax.w) != 0 &&
                                  gpu::as_uint(n.rmin.w) == gpu::as_uint(n.lmin.w) &&
                                  gpu::as_uint(n.rmax.w) == gpu::as_uint(n.lmax.w);
        if (!linked_twice) // a one-child node links its leaf twice
            add(n.rmin.x, n.rmin.y, n.rmin.z, n.rmax.x, n.rmax.y, n.rmax.z,
                gpu::as_uint(n.rmin.w), gpu::as_uint(n.rmax.w));
    }
    for (const gpu::Bvh4Node& n : bvh.nodes4)
        for (int k = 0; k < 4; ++k)
            add((&n.min_x.x)[k], (&n.min_y.x)[k], (&n.min_z.x)[k], (&n.max_x.x)[k],
                (&n.max_y.x)[k], (&n.max_z.x)[k], (&n.child.x)[k], (&n.count.x)[k]);
    for (const gpu::Bvh8Node& n : bvh.nodes8)
        for (int k = 0; k < 8; ++k)
            add(n.min_x[k], n.min_y[k], n.min_z[k], n.max_x[k], n.max_y[k], n.max_z[k],
                n.child[k], n.count[k]);
    return out;
}

/// indirect-room's geometry: a closed room of six rectangles, a thin partition (a box of six
/// rectangles) and a small rectangular light on the floor behind it; two triangles per
/// rectangle, rectangle r being triangles 2r and 2r + 1. The light is rectangle 12.
TriangleMesh room_mesh() {
    TriangleMesh mesh;
    mesh.source = "room";
    auto quad = [&](glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d) {
        const auto i = static_cast<unsigned>(mesh.positions.size());
        mesh.positions.insert(mesh.positions.end(), {a, b, c, d});
        mesh.triangles.push_back(glm::uvec3(i, i + 1, i + 2));
        mesh.triangles.push_back(glm::uvec3(i, i + 2, i + 3));
    };
    auto box = [&](glm::vec3 lo, glm::vec3 hi) {
        const glm::vec3 p[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z},
                                {lo.x, hi.y, lo.z}, {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z},
                                {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z}};
        quad(p[0], p[1], p[2], p[3]), quad(p[4], p[5], p[6], p[7]); // z faces
        quad(p[0], p[1], p[5], p[4]), quad(p[3], p[2], p[6], p[7]); // y faces
        quad(p[0], p[3], p[7], p[4]), quad(p[1], p[2], p[6], p[5]); // x faces
    };
    box({-2.0f, 0.0f, -3.0f}, {2.0f, 2.5f, 1.0f});     // the room: rectangles 0-5
    box({-1.14f, 0.0f, -2.8f}, {-1.06f, 2.0f, -0.4f}); // the partition: rectangles 6-11
    quad({-1.9f, 0.02f, -2.1f}, {-1.3f, 0.02f, -2.1f}, {-1.3f, 0.02f, -1.1f},
         {-1.9f, 0.02f, -1.1f}); // the light: rectangle 12
    return mesh;
}
} // namespace

TEST_SUITE("bvh") {
    TEST_CASE("every mesh gives a valid BVH within the depth and leaf-size limits") {
        EmbreeDevice device;
        for (const char* name : {"knot.ply", "degenerate.obj", "far_slivers.ply", "knot_small.obj"}) {
            const TriangleMesh mesh = load_mesh(mesh_path(name));
            const FlatBvh bvh = build_bvh(device, mesh, 2);
            INFO(name);
            CHECK_NOTHROW(check_bvh(bvh, mesh.triangle_count()));
            CHECK(bvh.triangles.size() == mesh.triangle_count());
            CHECK(bvh.depth <= BVH_MAX_DEPTH);
            CHECK(bvh.leaves == bvh.nodes.size() + 1); // a full binary tree
            const FlatBvh bvh4 = build_bvh(device, mesh, 4);
            CHECK_NOTHROW(check_bvh(bvh4, mesh.triangle_count()));
            CHECK(bvh4.depth <= BVH4_MAX_DEPTH);
            CHECK(bvh4.depth < bvh.depth);
            CHECK(bvh4.nodes4.size() < bvh.nodes.size());
            // four-triangle blocks: whole blocks, padded, every triangle once
            const FlatBvh bvh4t = build_bvh(device, mesh, 4, LeafFormat::tri4);
            CHECK(bvh4t.tri4);
            CHECK_NOTHROW(check_bvh(bvh4t, mesh.triangle_count()));
            CHECK(bvh4t.triangles.size() % 4 == 0);
            CHECK(bvh4t.triangles.size() < 2 * mesh.triangle_count() + 8);
            // eight-wide, with either leaf format: shallower, fewer nodes
            for (const LeafFormat leaves : {LeafFormat::records, LeafFormat::tri4}) {
                const FlatBvh bvh8 = build_bvh(device, mesh, 8, leaves);
                CHECK_NOTHROW(check_bvh(bvh8, mesh.triangle_count()));
                CHECK(bvh8.depth <= bvh4.depth);
                CHECK(bvh8.nodes8.size() < bvh4.nodes4.size());
            }
        }
    }

    TEST_CASE(
        "blocks of four need a four-wide BVH of triangles, and check_bvh reads their format") {
        EmbreeDevice device;
        CHECK_THROWS_WITH_AS(
            build_bvh(device, load_mesh(mesh_path("knot_small.obj")), 2, LeafFormat::tri4),
            doctest::Contains("eight-wide BVH of triangles only"), Error);
        const TriangleMesh analytic = test::mesh_with_analytic_shapes();
        CHECK_THROWS_WITH_AS(build_bvh(device, analytic, 4, LeafFormat::tri4),
                             doctest::Contains("eight-wide BVH of triangles only"), Error);
        const TriangleMesh mesh = load_mesh(mesh_path("knot_small.obj"));
        const FlatBvh good = build_bvh(device, mesh, 4, LeafFormat::tri4);
        // each record a leaf stands for is the triangle's own (primitive_record)
        std::size_t checked = 0;
        for (const gpu::Bvh4Node& n : good.nodes4)
            for (int k = 0; k < 4; ++k) {
                const unsigned count = (&n.count.x)[k], first = (&n.child.x)[k];
                for (unsigned i = 0; i < count; ++i, ++checked) {
                    const gpu::BvhTriangle r = leaf_record(good, first, i);
                    const gpu::BvhTriangle expected = primitive_record(mesh, gpu::as_uint(r.v0.w));
                    REQUIRE(std::memcmp(&r, &expected, sizeof r) == 0);
                }
            }
        CHECK(checked == mesh.triangle_count());
        // each rule of the format, broken in one block, is reported: a padding lane given an id
        // or a vertex, ids out of order, and (below) a leaf moved off a block's start
        const TriangleMesh degenerate = load_mesh(mesh_path("degenerate.obj"));
        const FlatBvh padded = build_bvh(device, degenerate, 4, LeafFormat::tri4);
        // applies `edit` to the last block of the first leaf of 2 or 3 (mod 4) triangles
        auto broken = [&](auto&& edit) {
            FlatBvh bad = padded;
            for (gpu::Bvh4Node& n : bad.nodes4)
                for (int k = 0; k < 4; ++k) {
                    const unsigned count = (&n.count.x)[k];
                    if (count % 4 != 2 && count % 4 != 3) continue;
                    gpu::BvhTri4 b;
                    const unsigned last = (&n.child.x)[k] + (count - 1) / 4 * 4;
                    std::memcpy(&b, &bad.triangles[last], sizeof b);
                    edit(b);
                    std::memcpy(&bad.triangles[last], &b, sizeof b);
                    return bad;
                }
            FAIL("no leaf of 2 or 3 (mod 4) triangles");
            return bad;
        };
        const std::size_t n_degenerate = degenerate.triangle_count();
        CHECK_NOTHROW(check_bvh(padded, n_degenerate));
        CHECK_THROWS_WITH_AS(check_bvh(broken([](gpu::BvhTri4& b) { b.prim.w = 0; }), n_degenerate),
                             doctest::Contains("pads a lane with a primitive id"), Error);
        CHECK_THROWS_WITH_AS(
            check_bvh(broken([](gpu::BvhTri4& b) { b.cz.w = 1.0f; }), n_degenerate),
            doctest::Contains("pads a lane with a nonzero vertex"), Error);
        CHECK_THROWS_WITH_AS(
            check_bvh(broken([](gpu::BvhTri4& b) { std::swap(b.prim.x, b.prim.y); }), n_degenerate),
            doctest::Contains("increasing primitive id"), Error);
        CHECK_THROWS_WITH_AS(
            check_bvh(broken([](gpu::BvhTri4& b) { b.nz.w = 1.0f; }), n_degenerate),
            doctest::Contains("pads a lane with a nonzero vertex or normal"), Error);
        // the plane normal the triangle test reads, in a block's lane and in a record
        CHECK_THROWS_WITH_AS(
            check_bvh(broken([](gpu::BvhTri4& b) { b.nx.x = std::nextafter(b.nx.x, 1e30f); }),
                      n_degenerate),
            doctest::Contains("stale plane normal"), Error);
        FlatBvh records = build_bvh(device, mesh, 4, LeafFormat::records);
        CHECK_NOTHROW(check_bvh(records, mesh.triangle_count()));
        gpu::float4& plane_n = records.triangles[records.triangles.size() / 2].plane_n;
        plane_n.y = std::nextafter(plane_n.y, 1e30f);
        CHECK_THROWS_WITH_AS(check_bvh(records, mesh.triangle_count()),
                             doctest::Contains("stale plane normal"), Error);
        FlatBvh with_shapes = build_bvh(device, analytic, 4, LeafFormat::records);
        CHECK_NOTHROW(check_bvh(with_shapes, analytic.primitive_count()));
        const auto sphere = std::find_if(
            with_shapes.triangles.begin(), with_shapes.triangles.end(),
            [](const gpu::BvhTriangle& r) { return gpu::as_uint(r.v1.w) == BVH_PRIM_SPHERE; });
        REQUIRE(sphere != with_shapes.triangles.end());
        sphere->plane_n.x = 1.0f; // an analytic record's is zero
        CHECK_THROWS_WITH_AS(check_bvh(with_shapes, analytic.primitive_count()),
                             doctest::Contains("stale plane normal"), Error);
        FlatBvh shifted = good;
        for (gpu::Bvh4Node& n : shifted.nodes4)
            for (int k = 0; k < 4; ++k)
                if ((&n.count.x)[k] != 0) (&n.child.x)[k] += 1;
        CHECK_THROWS_WITH_AS(check_bvh(shifted, mesh.triangle_count()),
                             doctest::Contains("whole block"), Error);
    }

    TEST_CASE("the preferred layout: eight-wide on CPUs with 8-float vectors, four-wide on narrower "
              "ones, two-wide elsewhere but in GPU forward renders of triangles, and blocks in "
              "every eight-wide tree on CPUs") {
        DeviceInfo cpu;
        cpu.type = "CPU";
        cpu.native_float_width = 8;
        CHECK(preferred_bvh_width(cpu) == 8);
        cpu.native_float_width = 16;
        CHECK(preferred_bvh_width(cpu) == 8);
        cpu.native_float_width = 4;
        CHECK(preferred_bvh_width(cpu) == 4);
        DeviceInfo gpu;
        gpu.type = "GPU";
        gpu.native_float_width = 8;
        CHECK(preferred_bvh_width(gpu) == 2);
        CHECK(preferred_leaf_format(cpu, 36, 8) == LeafFormat::tri4);
        CHECK(preferred_leaf_format(cpu, 36, 4) == LeafFormat::records);
        CHECK(preferred_leaf_format(cpu, k_tri4_min_triangles, 4) == LeafFormat::tri4);
        CHECK(preferred_leaf_format(cpu, k_tri4_min_triangles, 2) == LeafFormat::records);
        CHECK(preferred_leaf_format(gpu, k_tri4_min_triangles, 8) == LeafFormat::records);
        // forward renders: GPUs take eight-wide trees for triangle scenes only; CPUs as above
        CHECK(forward_bvh_width(gpu, false) == 8);
        CHECK(forward_bvh_width(gpu, true) == 2);
        CHECK(forward_bvh_width(cpu, true) == 4);
        cpu.native_float_width = 8;
        CHECK(forward_bvh_width(cpu, false) == 8);
        CHECK(forward_bvh_width(cpu, true) == 8);
    }

    TEST_CASE("prefetch: eight-wide trees of large meshes on CPUs, unless the Tuning "
              "($TANDEM_BVH_PREFETCH) says otherwise") {
        const DeviceInfo cpu = device_of_type("CPU"), gpu = device_of_type("GPU");
        CHECK(prefers_prefetch(cpu, k_prefetch_min_triangles, 8));
        CHECK(!prefers_prefetch(cpu, k_prefetch_min_triangles - 1, 8));
        CHECK(!prefers_prefetch(cpu, 36, 8));
        CHECK(!prefers_prefetch(cpu, k_prefetch_min_triangles, 4));
        CHECK(!prefers_prefetch(gpu, k_prefetch_min_triangles, 8));
        Tuning tuning;
        CHECK(policy_for(cpu, k_prefetch_min_triangles, 8, tuning).prefetch);
        CHECK(!policy_for(gpu, k_prefetch_min_triangles, 8, tuning).prefetch);
        tuning.bvh_prefetch = true;
        CHECK(policy_for(gpu, 36, 2, tuning).prefetch);
        tuning.bvh_prefetch = false;
        CHECK(!policy_for(cpu, k_prefetch_min_triangles, 8, tuning).prefetch);
        {
            const test::ScopedEnv on("TANDEM_BVH_PREFETCH", "1");
            CHECK(tuning_from_environment().bvh_prefetch == std::optional<bool>(true));
        }
        {
            const test::ScopedEnv unset("TANDEM_BVH_PREFETCH", nullptr);
            CHECK(!tuning_from_environment().bvh_prefetch);
        }
        const test::ScopedEnv bad("TANDEM_BVH_PREFETCH", "yes");
        CHECK_THROWS_WITH_AS(tuning_from_environment(),
                             doctest::Contains("TANDEM_BVH_PREFETCH='yes'"), Error);
    }

    TEST_CASE("camera packets: CPUs with the eight-wide tree of blocks, unless the Tuning "
              "($TANDEM_CAMERA_PACKETS) says otherwise") {
        const DeviceInfo cpu = device_of_type("CPU"), gpu = device_of_type("GPU");
        CHECK(prefers_camera_packets(cpu, 8, true));
        CHECK(!prefers_camera_packets(cpu, 8, false));
        CHECK(!prefers_camera_packets(cpu, 4, true));
        CHECK(!prefers_camera_packets(gpu, 8, true));
        Tuning tuning;
        CHECK(policy_for(cpu, 36, 8, tuning).camera_packets);
        CHECK(!policy_for(cpu, 36, 4, tuning).camera_packets);
        CHECK(!policy_for(gpu, 36, 8, tuning).camera_packets);
        tuning.bvh_tri4_leaves = false; // the packets need blocks
        CHECK(!policy_for(cpu, 36, 8, tuning).camera_packets);
        tuning.bvh_tri4_leaves.reset();
        tuning.camera_packets = true;
        CHECK(!policy_for(gpu, 36, 8, tuning).camera_packets); // a GPU's eight-wide tree: records
        CHECK(!policy_for(cpu, 36, 2, tuning).camera_packets);
        tuning.bvh_tri4_leaves = true;
        CHECK(policy_for(gpu, 36, 8, tuning).camera_packets);
        tuning = Tuning{};
        tuning.camera_packets = false;
        CHECK(!policy_for(cpu, 36, 8, tuning).camera_packets);
        const test::ScopedEnv bad("TANDEM_CAMERA_PACKETS", "on");
        CHECK_THROWS_WITH_AS(tuning_from_environment(),
                             doctest::Contains("TANDEM_CAMERA_PACKETS='on'"), Error);
    }

    TEST_CASE("check_bvh reads eight-wide nodes: unused lanes, child boxes, leaf ranges") {
        EmbreeDevice device;
        const TriangleMesh mesh = load_mesh(mesh_path("knot_small.obj"));
        const FlatBvh good = build_bvh(device, mesh, 8);
        REQUIRE(good.nodes8.size() > 1);
        CHECK_NOTHROW(check_bvh(good, mesh.triangle_count()));
        // the first lane of some node that is a leaf, an interior child, or unused
        auto first_lane = [&](auto&& pred) -> std::pair<std::size_t, int> {
            for (std::size_t i = 0; i < good.nodes8.size(); ++i)
                for (int k = 0; k < 8; ++k)
                    if (pred(good.nodes8[i], k)) return {i, k};
            FAIL("no such lane");
            return {0, 0};
        };
        const auto unused = first_lane(
            [](const gpu::Bvh8Node& n, int k) { return n.min_x[k] > n.max_x[k]; });
        FlatBvh bad = good;
        bad.nodes8[unused.first].count[unused.second] = 1;
        CHECK_THROWS_WITH_AS(check_bvh(bad, mesh.triangle_count()),
                             doctest::Contains("leaf in an unused lane"), Error);
        const auto inner = first_lane([](const gpu::Bvh8Node& n, int k) {
            return n.min_x[k] <= n.max_x[k] && n.count[k] == 0;
        });
        bad = good;
        bad.nodes8[inner.first].max_y[inner.second] = bad.nodes8[inner.first].min_y[inner.second];
        CHECK_THROWS_WITH_AS(check_bvh(bad, mesh.triangle_count()),
                             doctest::Contains("does not contain"), Error);
        const auto leaf = first_lane([](const gpu::Bvh8Node& n, int k) {
            return n.min_x[k] <= n.max_x[k] && n.count[k] != 0;
        });
        bad = good;
        bad.nodes8[leaf.first].child[leaf.second] = static_cast<unsigned>(good.triangles.size());
        CHECK_THROWS_WITH_AS(check_bvh(bad, mesh.triangle_count()),
                             doctest::Contains("out of bounds"), Error);
        bad = good;
        bad.nodes8[inner.first].child[inner.second] = static_cast<unsigned>(good.nodes8.size());
        CHECK_THROWS_WITH_AS(check_bvh(bad, mesh.triangle_count()),
                             doctest::Contains("out of range"), Error);
    }

    TEST_CASE("every format misses a hit at exactly tmax and finds it just inside") {
        EmbreeDevice device;
        const TriangleMesh mesh = load_mesh(mesh_path("knot_small.obj"));
        const FlatBvh bvh = build_bvh(device, mesh, 2), bvh4 = build_bvh(device, mesh, 4),
                      bvh4t = build_bvh(device, mesh, 4, LeafFormat::tri4),
                      bvh8 = build_bvh(device, mesh, 8),
                      bvh8t = build_bvh(device, mesh, 8, LeafFormat::tri4);
        int tested = 0;
        for (gpu::Ray ray : make_random_rays(mesh.bounds(), 2000, 13)) {
            const gpu::Hit h = brute_force(bvh, ray);
            if (h.prim == HIT_NONE || !(h.t > 0.0f)) continue;
            for (const float tmax : {h.t, std::nextafter(h.t, INFINITY)}) {
                ray.dir.w = tmax;
                const bool hit = tmax > h.t; // [tmin, tmax): the hit at t == tmax is outside
                INFO("tmax " << tmax << ", hit at " << h.t);
                REQUIRE(
                    (gpu::bvh_intersect_closest(bvh.nodes.data(), bvh.triangles.data(), ray).prim !=
                     HIT_NONE) == hit);
                REQUIRE(
                    (gpu::bvh4_intersect_closest(bvh4.nodes4.data(), bvh4.triangles.data(), ray, 0)
                         .prim != HIT_NONE) == hit);
                REQUIRE((gpu::bvh4_intersect_closest(bvh4t.nodes4.data(), bvh4t.triangles.data(),
                                                     ray, 1)
                             .prim != HIT_NONE) == hit);
                REQUIRE(gpu::bvh_intersect_any(bvh.nodes.data(), bvh.triangles.data(), ray) ==
                        int(hit));
                REQUIRE(gpu::bvh4_intersect_any(bvh4.nodes4.data(), bvh4.triangles.data(), ray,
                                                0) == int(hit));
                REQUIRE(gpu::bvh4_intersect_any(bvh4t.nodes4.data(), bvh4t.triangles.data(), ray,
                                                1) == int(hit));
                for (const FlatBvh* b8 : {&bvh8, &bvh8t}) {
                    REQUIRE((host_closest(*b8, ray).prim != HIT_NONE) == hit);
                    REQUIRE(host_any(*b8, ray) == int(hit));
                }
            }
            ++tested;
        }
        CHECK(tested > 200);
    }

    TEST_CASE("leaves repacked by the SAH of their tests: a rectangle's two triangles share a "
              "leaf, a small light gets a box of its own") {
        // Embree fills wide nodes by splitting children whatever their SAH: it parted the two
        // triangles of indirect-room's floor (leaves with the same box) and left its light in
        // the leaf of the wall beside it, a box every shadow ray toward the light enters.
        EmbreeDevice device;
        const TriangleMesh mesh = room_mesh();
        for (int layout : {2, 4, 5, 8, 9}) { // 5, 9: blocks of four
            const FlatBvh bvh = build_bvh(device, mesh, layout & ~1,
                                          layout % 2 ? LeafFormat::tri4 : LeafFormat::records);
            INFO("width " << (layout & ~1) << std::string(layout % 2 ? ", blocks" : ", records"));
            REQUIRE_NOTHROW(check_bvh(bvh, mesh.triangle_count()));
            const std::vector<LeafContents> leaves = leaves_of(bvh);
            std::vector<int> leaf_of(mesh.triangle_count(), -1);
            for (std::size_t l = 0; l < leaves.size(); ++l)
                for (unsigned p : leaves[l].prims) leaf_of.at(p) = static_cast<int>(l);
            for (unsigned r = 0; r < mesh.triangle_count() / 2; ++r) {
                INFO("rectangle " << r);
                CHECK(leaf_of[2 * r] == leaf_of[2 * r + 1]);
            }
            if ((layout & ~1) == 8) { // with free lanes: the light alone, in its own flat box
                const LeafContents& light = leaves.at(leaf_of[24]);
                CHECK(light.prims == std::vector<unsigned>{24, 25});
                CHECK(light.hi.y - light.lo.y == 0.0f);
            }
        }
    }

    TEST_CASE("repacked or as Embree built it, every layout finds the same hits") {
        EmbreeDevice device;
        for (const TriangleMesh& mesh : {room_mesh(), load_mesh(mesh_path("knot_small.obj"))}) {
            const std::vector<gpu::Ray> rays = make_random_rays(mesh.bounds(), 4096, 11);
            for (int layout : {2, 8, 9}) { // 9: eight-wide with blocks of four
                const LeafFormat leaves = layout % 2 ? LeafFormat::tri4 : LeafFormat::records;
                const FlatBvh packed = build_bvh(device, mesh, layout & ~1, leaves, true);
                const FlatBvh plain = build_bvh(device, mesh, layout & ~1, leaves, false);
                INFO(mesh.source << ", layout " << layout);
                REQUIRE_NOTHROW(check_bvh(plain, mesh.triangle_count()));
                int hits = 0, differ = 0;
                for (const gpu::Ray& ray : rays) {
                    const gpu::Hit a = host_closest(packed, ray), b = host_closest(plain, ray);
                    differ += std::memcmp(&a, &b, sizeof a) != 0;
                    differ += host_any(packed, ray) != host_any(plain, ray);
                    hits += a.prim != HIT_NONE;
                }
                CHECK(differ == 0);
                CHECK(hits > 1000);
            }
        }
    }

    TEST_CASE("two builds of one mesh are bitwise identical") {
        EmbreeDevice device;
        const TriangleMesh mesh = load_mesh(mesh_path("knot.ply"));
        for (int width : {2, 4, 5, 8, 9}) { // 5, 9: four- and eight-wide with blocks of four
            const LeafFormat leaves = width % 2 ? LeafFormat::tri4 : LeafFormat::records;
            const FlatBvh a = build_bvh(device, mesh, width & ~1, leaves);
            const FlatBvh b = build_bvh(device, mesh, width & ~1, leaves);
            CHECK(same_bytes(a.nodes, b.nodes));
            CHECK(same_bytes(a.nodes4, b.nodes4));
            CHECK(same_bytes(a.nodes8, b.nodes8));
            CHECK(same_bytes(a.triangles, b.triangles));
        }
    }

    TEST_CASE("a one-triangle mesh has a root whose leaf is linked twice") {
        EmbreeDevice device;
        TriangleMesh mesh;
        mesh.source = "one-triangle";
        mesh.positions = {glm::vec3(0, 0, 0), glm::vec3(1, 0, 0), glm::vec3(0, 1, 0)};
        mesh.triangles = {glm::uvec3(0, 1, 2)};
        // An asymmetric point, so swapped barycentrics would show.
        const gpu::Ray ray = make_ray(glm::vec3(0.25f, 0.125f, 1.0f), glm::vec3(0, 0, -1));
        const gpu::Ray away = make_ray(glm::vec3(0.25f, 0.125f, 1.0f), glm::vec3(0, 0, 1));
        const FlatBvh bvh = build_bvh(device, mesh, 2);
        REQUIRE(bvh.nodes.size() == 1);
        CHECK_NOTHROW(check_bvh(bvh, 1));
        const FlatBvh bvh4 = build_bvh(device, mesh, 4);
        REQUIRE(bvh4.nodes4.size() == 1);
        CHECK_NOTHROW(check_bvh(bvh4, 1)); // one used lane, three empty (inverted) lanes
        const FlatBvh bvh4t = build_bvh(device, mesh, 4, LeafFormat::tri4);
        CHECK_NOTHROW(check_bvh(bvh4t, 1)); // one block: one triangle, three padding lanes
        const FlatBvh bvh8 = build_bvh(device, mesh, 8),
                      bvh8t = build_bvh(device, mesh, 8, LeafFormat::tri4);
        REQUIRE(bvh8.nodes8.size() == 1);
        CHECK_NOTHROW(check_bvh(bvh8, 1)); // one used lane, seven empty lanes
        CHECK_NOTHROW(check_bvh(bvh8t, 1));
        for (const FlatBvh* b8 : {&bvh8, &bvh8t}) {
            const gpu::Hit h8 = host_closest(*b8, ray), h2 = host_closest(bvh, ray);
            CHECK(std::memcmp(&h8, &h2, sizeof h8) == 0);
            CHECK(host_closest(*b8, away).prim == HIT_NONE);
            CHECK(host_any(*b8, away) == 0);
            CHECK(host_any(*b8, ray) == 1);
        }
        for (const gpu::Hit h :
             {gpu::bvh_intersect_closest(bvh.nodes.data(), bvh.triangles.data(), ray),
              gpu::bvh4_intersect_closest(bvh4.nodes4.data(), bvh4.triangles.data(), ray,
                                          bvh4.tri4),
              gpu::bvh4_intersect_closest(bvh4t.nodes4.data(), bvh4t.triangles.data(), ray,
                                          bvh4t.tri4)}) {
            CHECK(h.prim == 0);
            CHECK(h.t == 1.0f);
            CHECK(h.u == 0.25f);  // weight of v1 = (1, 0, 0)
            CHECK(h.v == 0.125f); // weight of v2 = (0, 1, 0)
        }
        CHECK(
            gpu::bvh4_intersect_closest(bvh4.nodes4.data(), bvh4.triangles.data(), away, bvh4.tri4)
                .prim == HIT_NONE);
        CHECK(gpu::bvh4_intersect_any(bvh4.nodes4.data(), bvh4.triangles.data(), away, bvh4.tri4) ==
              0);
        CHECK(gpu::bvh4_intersect_closest(bvh4t.nodes4.data(), bvh4t.triangles.data(), away, 1)
                  .prim == HIT_NONE);
        CHECK(gpu::bvh4_intersect_any(bvh4t.nodes4.data(), bvh4t.triangles.data(), away, 1) == 0);
        CHECK(gpu::bvh4_intersect_any(bvh4t.nodes4.data(), bvh4t.triangles.data(), ray, 1) == 1);
    }

    TEST_CASE("host traversal equals brute force over all triangles") {
        EmbreeDevice device;
        for (const char* name : {"knot_small.obj", "degenerate.obj"}) {
            INFO(name);
            const TriangleMesh mesh = load_mesh(mesh_path(name));
            const FlatBvh bvh = build_bvh(device, mesh, 2);
            const FlatBvh bvh4 = build_bvh(device, mesh, 4);
            const FlatBvh bvh4t = build_bvh(device, mesh, 4, LeafFormat::tri4);
            const FlatBvh bvh8 = build_bvh(device, mesh, 8);
            const FlatBvh bvh8t = build_bvh(device, mesh, 8, LeafFormat::tri4);
            const std::vector<gpu::Ray> rays = make_random_rays(mesh.bounds(), 4000, 7);
            int hits = 0;
            for (const gpu::Ray& ray : rays) {
                const gpu::Hit b = brute_force(bvh, ray);
                // the same triangle test and tie rule: the very same hit, bit for bit
                const gpu::Hit a = gpu::bvh_intersect_closest(bvh.nodes.data(), bvh.triangles.data(), ray);
                REQUIRE(std::memcmp(&a, &b, sizeof a) == 0);
                const gpu::Hit a4 = gpu::bvh4_intersect_closest(
                    bvh4.nodes4.data(), bvh4.triangles.data(), ray, bvh4.tri4);
                REQUIRE(std::memcmp(&a4, &b, sizeof a) == 0);
                REQUIRE(gpu::bvh_intersect_any(bvh.nodes.data(), bvh.triangles.data(), ray) ==
                        (b.prim != HIT_NONE));
                REQUIRE(gpu::bvh4_intersect_any(bvh4.nodes4.data(), bvh4.triangles.data(), ray,
                                                bvh4.tri4) == (b.prim != HIT_NONE));
                // four triangles per float4 test: the same bits per triangle, the same tie rule
                const gpu::Hit a4t = gpu::bvh4_intersect_closest(bvh4t.nodes4.data(),
                                                                 bvh4t.triangles.data(), ray, 1);
                REQUIRE(std::memcmp(&a4t, &b, sizeof a) == 0);
                REQUIRE(gpu::bvh4_intersect_any(bvh4t.nodes4.data(), bvh4t.triangles.data(), ray,
                                                1) == (b.prim != HIT_NONE));
                // eight boxes per float8 test, either leaf format
                for (const FlatBvh* b8 : {&bvh8, &bvh8t}) {
                    const gpu::Hit a8 = host_closest(*b8, ray);
                    REQUIRE(std::memcmp(&a8, &b, sizeof a) == 0);
                    REQUIRE(host_any(*b8, ray) == (b.prim != HIT_NONE));
                }
                hits += b.prim != HIT_NONE;
            }
            CHECK(hits > 400); // the rays really exercise the mesh
        }
    }

    TEST_CASE("analytic spheres and disks: the BVHs equal brute force, and hits match double precision") {
        EmbreeDevice device;
        const TriangleMesh mesh = test::mesh_with_analytic_shapes();
        const FlatBvh bvh = build_bvh(device, mesh, 2);
        const FlatBvh bvh4 = build_bvh(device, mesh, 4);
        CHECK_NOTHROW(check_bvh(bvh, mesh.primitive_count()));
        CHECK_NOTHROW(check_bvh(bvh4, mesh.primitive_count()));
        const FlatBvh bvh8 = build_bvh(device, mesh, 8);
        CHECK_NOTHROW(check_bvh(bvh8, mesh.primitive_count()));
        const double diag = glm::length(glm::dvec3(mesh.bounds().extent()));
        const auto n_tris = static_cast<unsigned>(mesh.triangle_count());
        const auto first_disk = static_cast<unsigned>(n_tris + mesh.spheres.size());
        int sphere_hits = 0, inside_hits = 0, disk_hits = 0;
        double worst_t = 0.0, worst_point = 0.0, worst_disk_t = 0.0, worst_local = 0.0;
        for (const gpu::Ray& ray : make_random_rays(mesh.bounds(), 20000, 9)) {
            const gpu::Hit b = brute_force(bvh, ray);
            const gpu::Hit a = gpu::bvh_intersect_closest(bvh.nodes.data(), bvh.triangles.data(), ray);
            const gpu::Hit a4 = gpu::bvh4_intersect_closest(bvh4.nodes4.data(),
                                                            bvh4.triangles.data(), ray, bvh4.tri4);
            REQUIRE(std::memcmp(&a, &b, sizeof a) == 0);
            REQUIRE(std::memcmp(&a4, &b, sizeof a) == 0);
            const gpu::Hit a8 = host_closest(bvh8, ray);
            REQUIRE(std::memcmp(&a8, &b, sizeof a) == 0);
            REQUIRE(host_any(bvh8, ray) == (b.prim != HIT_NONE));
            REQUIRE(gpu::bvh_intersect_any(bvh.nodes.data(), bvh.triangles.data(), ray) == (b.prim != HIT_NONE));
            REQUIRE(gpu::bvh4_intersect_any(bvh4.nodes4.data(), bvh4.triangles.data(), ray,
                                            bvh4.tri4) == (b.prim != HIT_NONE));
            if (b.prim == HIT_NONE || b.prim < n_tris) continue;
            const glm::dvec3 d(ray.dir.x, ray.dir.y, ray.dir.z);
            if (b.prim >= first_disk) { // a disk: its plane's t and the local point, in double
                glm::dvec2 local(0.0);
                const double t = disk_root(ray, mesh.disks[b.prim - first_disk], &local);
                REQUIRE(t >= 0.0);
                worst_disk_t = std::max(worst_disk_t, std::fabs(b.t - t) * glm::length(d) / diag);
                worst_local = std::max({worst_local, std::fabs(b.u - local.x), std::fabs(b.v - local.y)});
                disk_hits += 1;
                continue;
            }
            // a sphere: the root in double precision, and the decoded point on the ray
            const Sphere& sp = mesh.spheres[b.prim - n_tris];
            const double t = sphere_root(ray, sp);
            REQUIRE(t >= 0.0);
            const double dlen = glm::length(d);
            worst_t = std::max(worst_t, std::fabs(b.t - t) * dlen / diag);
            float nx, ny, nz;
            gpu::bvh_oct_decode(b.u, b.v, &nx, &ny, &nz);
            const glm::dvec3 p = glm::dvec3(sp.center) + double(sp.radius) * glm::dvec3(nx, ny, nz);
            const glm::dvec3 on_ray = glm::dvec3(ray.org.x, ray.org.y, ray.org.z) + t * d;
            worst_point = std::max(worst_point, glm::length(p - on_ray) / diag);
            sphere_hits += 1;
            inside_hits += glm::length(glm::dvec3(ray.org.x, ray.org.y, ray.org.z) - glm::dvec3(sp.center)) < sp.radius;
        }
        MESSAGE("sphere hits " << sphere_hits << " (" << inside_hits << " from inside); worst |dt| "
                << worst_t << ", worst point " << worst_point << " of the diagonal; disk hits "
                << disk_hits << ", worst |dt| " << worst_disk_t << ", worst local " << worst_local);
        CHECK(sphere_hits > 1000);
        CHECK(disk_hits > 200);
        CHECK(worst_disk_t < 1e-6);
        CHECK(worst_local < 1e-4);
        CHECK(inside_hits > 10);
        CHECK(worst_t < 1e-6);
        CHECK(worst_point < 1e-6);
    }

    TEST_CASE("analytic spheres: distant and grazing rays, tmin past the near side") {
        TriangleMesh mesh;
        mesh.source = "one sphere";
        mesh.spheres.push_back(Sphere{glm::vec3(1e4f, -2e4f, 3e4f), 1.0f, 1.0f});
        EmbreeDevice device;
        const FlatBvh bvh = build_bvh(device, mesh, 4);
        const glm::vec3 c = mesh.spheres[0].center;
        auto hit = [&](glm::vec3 o, glm::vec3 d, float tmin = 0.0f) {
            gpu::Ray r = make_ray(o, d);
            r.org.w = tmin;
            return gpu::bvh4_intersect_closest(bvh.nodes4.data(), bvh.triangles.data(), r,
                                               bvh.tri4);
        };
        // from 1e4 away, head on: t is the distance less the radius, to float precision
        const gpu::Hit h = hit(c + glm::vec3(0.0f, 0.0f, 1e4f), glm::vec3(0.0f, 0.0f, -1.0f));
        REQUIRE(h.prim == 0u);
        CHECK(h.t == doctest::Approx(1e4 - 1.0).epsilon(1e-6));
        // the direction decodes to +z
        float nx, ny, nz;
        gpu::bvh_oct_decode(h.u, h.v, &nx, &ny, &nz);
        CHECK(nz == doctest::Approx(1.0).epsilon(1e-6));
        // the same ray starting past the near side finds the far side
        const gpu::Hit far = hit(c + glm::vec3(0.0f, 0.0f, 1e4f), glm::vec3(0.0f, 0.0f, -1.0f), 1e4f);
        REQUIRE(far.prim == 0u);
        CHECK(far.t == doctest::Approx(1e4 + 1.0).epsilon(1e-6));
        // grazing: offsets of 0.999 and 1.001 radii from the axis hit and miss
        CHECK(hit(c + glm::vec3(0.999f, 0.0f, 50.0f), glm::vec3(0.0f, 0.0f, -1.0f)).prim == 0u);
        CHECK(hit(c + glm::vec3(1.001f, 0.0f, 50.0f), glm::vec3(0.0f, 0.0f, -1.0f)).prim == HIT_NONE);
        // a direction of length 4 measures t in its units
        CHECK(hit(c + glm::vec3(0.0f, 9.0f, 0.0f), glm::vec3(0.0f, -4.0f, 0.0f)).t ==
              doctest::Approx(2.0).epsilon(1e-6));
        // a radius that is not positive is refused
        mesh.spheres[0].radius = 0.0f;
        CHECK_THROWS_WITH_AS(build_bvh(device, mesh, 4), doctest::Contains("positive, finite radius"),
                             Error);
    }

    TEST_CASE("analytic spheres: rays leaving a large or distant sphere never hit it again at once") {
        // A ground sphere of radius 1000 whose top is the origin, and a unit sphere 3e3 away: the
        // rounding of o - c (and of the rebuilt point) is larger than offset_ray_origin's step,
        // so these rays start on the surface to rounding (bvh_sphere_intersect's band).
        for (const Sphere& sp : {Sphere{glm::vec3(0.0f, -1000.0f, 0.0f), 1000.0f, 1.0f},
                                 Sphere{glm::vec3(3e3f, -2e3f, 1e3f), 1.0f, 1.0f}}) {
            TriangleMesh mesh;
            mesh.source = "sphere";
            mesh.spheres.push_back(sp);
            EmbreeDevice device;
            const FlatBvh bvh = build_bvh(device, mesh, 4);
            std::uint32_t state = 7u;
            auto uniform = [&] {
                state = state * 1664525u + 1013904223u;
                return static_cast<float>(state >> 8) * (1.0f / 16777216.0f) * 2.0f - 1.0f;
            };
            int outward_hits = 0, inward_misses = 0, inward = 0, immediate = 0;
            double worst_chord = 0.0;
            for (int i = 0; i < 4000; ++i) {
                // a point on the sphere near its top (the ground under a scene), as shading builds it
                const glm::vec3 dir = glm::normalize(glm::vec3(0.02f * uniform(), 1.0f, 0.02f * uniform()));
                float u, v, nx, ny, nz;
                gpu::bvh_oct_encode(dir.x, dir.y, dir.z, &u, &v);
                gpu::bvh_oct_decode(u, v, &nx, &ny, &nz);
                const gpu::float3 n = gpu::make_float3(nx, ny, nz);
                const gpu::float3 x = gpu::make_float3(sp.center.x + nx * sp.radius,
                                                       sp.center.y + ny * sp.radius,
                                                       sp.center.z + nz * sp.radius);
                glm::vec3 w(uniform(), uniform(), uniform());
                if (glm::length(w) < 1e-3f) continue;
                w = glm::normalize(w);
                const bool out = w.x * nx + w.y * ny + w.z * nz > 0.0f;
                const gpu::float3 o = gpu::offset_ray_origin(x, out ? n : gpu::make_float3(-nx, -ny, -nz));
                const gpu::Ray ray = make_ray({o.x, o.y, o.z}, w);
                const gpu::Hit h = gpu::bvh4_intersect_closest(bvh.nodes4.data(),
                                                               bvh.triangles.data(), ray, bvh.tri4);
                if (out) {
                    outward_hits += h.prim != HIT_NONE;
                    continue;
                }
                inward += 1;
                if (h.prim == HIT_NONE) {
                    inward_misses += 1;
                    continue;
                }
                // the chord from the surface point: 2 r |cos| for a unit direction. Far from the
                // world origin offset_ray_origin's step is large against a unit sphere (256 ulps
                // of 3e3: 0.06), so there only an immediate re-hit (t near 0) is an error.
                const double cos_in = -(double(w.x) * nx + double(w.y) * ny + double(w.z) * nz);
                if (sp.radius > 1.0f)
                    worst_chord = std::max(worst_chord, std::fabs(h.t - 2.0 * sp.radius * cos_in) / sp.radius);
                else
                    immediate += h.t < 1e-3f * sp.radius;
            }
            INFO("radius " << sp.radius << ": " << outward_hits << " outward rays hit, "
                           << inward_misses << " of " << inward << " inward rays missed, worst chord error "
                           << worst_chord << " radii, " << immediate << " immediate re-hits");
            CHECK(outward_hits == 0);
            CHECK(immediate == 0);
            CHECK(inward > 1000);
            CHECK(inward_misses == 0);
            CHECK(worst_chord < 1e-4);
        }
    }

    TEST_CASE("invalid rays (NaN or Inf origin or direction, NaN interval) miss everything") {
        EmbreeDevice device;
        const TriangleMesh mesh = load_mesh(mesh_path("knot_small.obj"));
        const FlatBvh bvh = build_bvh(device, mesh, 2);
        const FlatBvh bvh4 = build_bvh(device, mesh, 4);
        const FlatBvh bvh4t = build_bvh(device, mesh, 4, LeafFormat::tri4);
        const float bad[] = {NAN, INFINITY, -INFINITY};
        // A ray aimed at the centroid of triangle 0, which hits when valid.
        const glm::uvec3 t0 = mesh.triangles[0];
        const glm::vec3 c = (mesh.positions[t0.x] + mesh.positions[t0.y] + mesh.positions[t0.z]) / 3.0f;
        const glm::vec3 o = c + glm::vec3(0.0f, 0.0f, 5.0f);
        const gpu::Ray good = make_ray(o, c - o);
        REQUIRE(gpu::bvh_intersect_any(bvh.nodes.data(), bvh.triangles.data(), good) == 1);
        int cases = 0;
        for (float x : bad)
            for (int slot = 0; slot < 8; ++slot) {
                gpu::Ray r = good;
                float* fields[8] = {&r.org.x, &r.org.y, &r.org.z, &r.dir.x,
                                    &r.dir.y, &r.dir.z, &r.org.w, &r.dir.w};
                if (slot == 7 && x == INFINITY) continue; // tmax = +inf is valid
                if (slot == 6 && x == -INFINITY) continue; // tmin = -inf is valid
                *fields[slot] = x;
                INFO("field " << slot << " = " << x);
                CHECK(gpu::bvh_intersect_closest(bvh.nodes.data(), bvh.triangles.data(), r).prim == HIT_NONE);
                CHECK(gpu::bvh4_intersect_closest(bvh4.nodes4.data(), bvh4.triangles.data(), r,
                                                  bvh4.tri4)
                          .prim == HIT_NONE);
                CHECK(gpu::bvh_intersect_any(bvh.nodes.data(), bvh.triangles.data(), r) == 0);
                CHECK(gpu::bvh4_intersect_any(bvh4.nodes4.data(), bvh4.triangles.data(), r,
                                              bvh4.tri4) == 0);
                CHECK(gpu::bvh4_intersect_closest(bvh4t.nodes4.data(), bvh4t.triangles.data(), r, 1)
                          .prim == HIT_NONE);
                CHECK(gpu::bvh4_intersect_any(bvh4t.nodes4.data(), bvh4t.triangles.data(), r, 1) ==
                      0);
                ++cases;
            }
        CHECK(cases == 22);
    }

    TEST_CASE("watertight: rays through shared edges and vertices of a fan never leak") {
        // A fan of 64 triangles around the origin in the z = 0 plane; rays aimed exactly at the
        // shared vertex and along the shared edges must hit some triangle.
        EmbreeDevice device;
        TriangleMesh mesh;
        mesh.source = "fan";
        mesh.positions.push_back(glm::vec3(0.0f));
        const int n = 64;
        for (int i = 0; i < n; ++i) {
            const float a = 6.2831853f * i / n;
            mesh.positions.emplace_back(std::cos(a), std::sin(a), 0.0f);
            mesh.triangles.emplace_back(0, 1 + i, 1 + (i + 1) % n);
        }
        const FlatBvh bvh = build_bvh(device, mesh, 2);
        const FlatBvh bvh4 = build_bvh(device, mesh, 4);
        const FlatBvh bvh4t = build_bvh(device, mesh, 4, LeafFormat::tri4);
        int leaks = 0;
        for (int i = 0; i < n; ++i)
            for (float s : {0.0f, 0.125f, 0.5f, 0.875f}) {
                const glm::vec3 p = s * mesh.positions[1 + i];
                for (const glm::vec3& o : {glm::vec3(0.3f, -0.2f, 1.0f), glm::vec3(-0.7f, 0.1f, -2.0f)}) {
                    const glm::vec3 d = p - o;
                    const gpu::Ray ray{gpu::make_float4(o.x, o.y, o.z, 0.0f),
                                       gpu::make_float4(d.x, d.y, d.z, INFINITY)};
                    leaks += gpu::bvh_intersect_closest(bvh.nodes.data(), bvh.triangles.data(), ray)
                                 .prim == HIT_NONE;
                    leaks += gpu::bvh4_intersect_closest(bvh4.nodes4.data(), bvh4.triangles.data(),
                                                         ray, bvh4.tri4)
                                 .prim == HIT_NONE;
                    leaks += gpu::bvh4_intersect_closest(bvh4t.nodes4.data(),
                                                         bvh4t.triangles.data(), ray, 1)
                                 .prim == HIT_NONE;
                }
            }
        CHECK(leaks == 0);
    }
}
