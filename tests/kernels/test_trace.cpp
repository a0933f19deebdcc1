// Device traversal against Embree's rtcIntersect1/rtcOccluded1 on >= 1M coherent and 1M incoherent
// rays per mesh, plus bitwise determinism and host/device parity of the shared traversal code
// (on PoCL for x86 the eight-wide loops take their BVH8_HOLD_NEAREST form, the host the other).
//
// Agreement rule, per ray (documented in README "Trace correctness"):
//   - hit/miss and primitive id equal, and t within 1e-4 relative: agree. The relative scale has a
//     floor of 1% of the mesh's diagonal (in units of the ray's direction length): a ray that
//     starts 1e-6 from the surface cannot resolve t to 1e-4 of itself in single precision;
//   - otherwise the ray is excused only if one of the two hits lies within 1e-5 x the mesh's
//     bounding-box diagonal of an edge of its triangle (the two intersectors round differently
//     there; Embree's default mode is not watertight), or if the two primitives are the same
//     triangle in space (a duplicate: both answers are the same surface at the same t);
//   - anything else fails the test. Excused rays are counted and printed, and must stay below
//     1e-3 of all rays, so the rule cannot hide a systematic error.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iostream>

#include <glm/geometric.hpp>

#include "bench/embree_scene.h"
#include "bench/rays.h"
#include "bench/tracer.h"
#include "shared/bvh8_traverse.h"
#include "support.h"

using namespace tandem;
using test::mesh_path;

namespace {

enum RayClass : unsigned char { k_agree, k_duplicate, k_near_edge, k_fail };

struct Tally {
    std::size_t rays = 0, hits = 0, agree = 0, near_edge = 0, duplicate = 0, failures = 0;
    double max_rel_t = 0.0;        ///< |dt| / max(t, 1% of the diagonal), over agreeing hits
    double max_strict_rel_t = 0.0; ///< |dt| / t, over agreeing hits
    double max_d_uv = 0.0;         ///< max |du|, |dv| over agreeing hits
    double max_d_pos = 0.0;        ///< max distance between the two barycentric hit points / diag
    std::size_t uv_off = 0;        ///< agreeing hits whose |du| or |dv| exceeds 1e-3
    std::vector<RayClass> cls;     ///< per ray
};

/// World-space distance from the hit point (u, v) of triangle `prim` to its nearest edge.
double edge_distance(const TriangleMesh& m, unsigned prim, float u, float v) {
    const glm::uvec3 t = m.triangles[prim];
    const glm::dvec3 a(m.positions[t.x]), b(m.positions[t.y]), c(m.positions[t.z]);
    const double area2 = glm::length(glm::cross(b - a, c - a));
    const double w[3] = {1.0 - u - v, static_cast<double>(u), static_cast<double>(v)};
    const double opposite[3] = {glm::length(c - b), glm::length(c - a), glm::length(b - a)};
    double d = 1e300;
    for (int k = 0; k < 3; ++k) // distance to the edge opposite vertex k = w_k * height_k
        if (opposite[k] > 0.0) d = std::min(d, std::fabs(w[k]) * area2 / opposite[k]);
    return d;
}

/// The hit point from the barycentrics, in double precision.
glm::dvec3 bary_point(const TriangleMesh& m, const gpu::Hit& h) {
    const glm::uvec3 t = m.triangles[h.prim];
    return (1.0 - h.u - h.v) * glm::dvec3(m.positions[t.x]) + double(h.u) * glm::dvec3(m.positions[t.y]) +
           double(h.v) * glm::dvec3(m.positions[t.z]);
}

bool same_triangle_in_space(const TriangleMesh& m, unsigned p, unsigned q) {
    std::array<glm::vec3, 3> a{}, b{};
    for (int k = 0; k < 3; ++k) {
        a[k] = m.positions[m.triangles[p][k]];
        b[k] = m.positions[m.triangles[q][k]];
    }
    auto less = [](const glm::vec3& x, const glm::vec3& y) {
        return std::tie(x.x, x.y, x.z) < std::tie(y.x, y.y, y.z);
    };
    std::sort(a.begin(), a.end(), less);
    std::sort(b.begin(), b.end(), less);
    return a == b;
}

Tally compare_closest(const TriangleMesh& mesh, const std::vector<gpu::Ray>& rays,
                      const std::vector<gpu::Hit>& dev, const std::vector<gpu::Hit>& ref) {
    const double edge_eps = 1e-5 * glm::length(glm::dvec3(mesh.bounds().extent()));
    const double diag = glm::length(glm::dvec3(mesh.bounds().extent()));
    Tally tally;
    tally.rays = rays.size();
    tally.cls.assign(rays.size(), k_fail);
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const gpu::Hit& d = dev[i];
        const gpu::Hit& e = ref[i];
        tally.hits += e.prim != HIT_NONE;
        const double dir_len = glm::length(glm::dvec3(rays[i].dir.x, rays[i].dir.y, rays[i].dir.z));
        const double t_scale = std::max(double(std::fabs(e.t)), 1e-2 * diag / dir_len);
        const double rel = std::fabs(double(d.t) - e.t) / t_scale;
        if (d.prim == e.prim) {
            if (d.prim == HIT_NONE || rel <= 1e-4) {
                if (d.prim != HIT_NONE) {
                    tally.max_rel_t = std::max(tally.max_rel_t, rel);
                    tally.max_strict_rel_t = std::max(
                        tally.max_strict_rel_t, std::fabs(double(d.t) - e.t) / std::fabs(e.t));
                    tally.max_d_uv = std::max({tally.max_d_uv, std::fabs(double(d.u) - e.u),
                                               std::fabs(double(d.v) - e.v)});
                    tally.uv_off += std::fabs(double(d.u) - e.u) > 1e-3 || std::fabs(double(d.v) - e.v) > 1e-3;
                    tally.max_d_pos = std::max(
                        tally.max_d_pos, glm::length(bary_point(mesh, d) - bary_point(mesh, e)) / diag);
                }
                ++tally.agree;
                tally.cls[i] = k_agree;
                continue;
            }
        }
        if (d.prim != HIT_NONE && e.prim != HIT_NONE && d.prim != e.prim &&
            same_triangle_in_space(mesh, d.prim, e.prim) && rel <= 1e-4) {
            ++tally.duplicate;
            tally.cls[i] = k_duplicate;
            continue;
        }
        const bool dev_edge = d.prim != HIT_NONE && edge_distance(mesh, d.prim, d.u, d.v) <= edge_eps;
        const bool ref_edge = e.prim != HIT_NONE && edge_distance(mesh, e.prim, e.u, e.v) <= edge_eps;
        if (dev_edge || ref_edge) {
            ++tally.near_edge;
            tally.cls[i] = k_near_edge;
            continue;
        }
        if (tally.failures++ < 5)
            std::cerr << "  ray " << i << ": device prim " << d.prim << " t " << d.t
                      << ", Embree prim " << e.prim << " t " << e.t << "\n";
    }
    return tally;
}

/// The layout's name in messages: BVH2, BVH4 or BVH8, the wider two maybe with blocks of four
/// triangles.
std::string layout_name(const FlatBvh& bvh) {
    return "BVH" + std::to_string(bvh.width) + (bvh.tri4 ? " tri4" : "");
}

void check_mesh(const char* name, int width, LeafFormat leaves = LeafFormat::records) {
    TANDEM_REQUIRE_DEVICE(ctx);
    const TriangleMesh mesh = load_mesh(mesh_path(name));
    EmbreeDevice embree;
    const FlatBvh bvh = build_bvh(embree, mesh, width, leaves);
    const EmbreeScene reference(embree, mesh, /*robust=*/true);
    Tracer tracer(*ctx, KernelLibrary::from_environment());
    const DeviceBvh dbvh(*ctx, bvh);

    const Bounds bounds = mesh.bounds();
    const std::pair<const char*, std::vector<gpu::Ray>> sets[] = {
        {"coherent", make_camera_rays(bounds, 1024, 1024)},
        {"incoherent", make_random_rays(bounds, 1 << 20, 11)},
    };
    for (const auto& [kind, rays] : sets) {
        INFO(name << ", " << layout_name(bvh) << ", " << kind << " rays");
        const std::size_t n = rays.size();
        REQUIRE(n >= 1000000);
        Buffer<gpu::Ray> drays(*ctx, "rays", rays);
        Buffer<gpu::Hit> dhits(*ctx, "hits", n);
        tracer.closest(dbvh, drays, dhits);
        const std::vector<gpu::Hit> dev = dhits.download();
        std::vector<gpu::Hit> ref;
        reference.intersect(rays, ref, 2, EmbreeMode::single);

        // Closest hit against Embree.
        const Tally t = compare_closest(mesh, rays, dev, ref);
        std::cout << "[trace] " << name << " " << layout_name(bvh) << " " << kind << ": " << t.rays
                  << " rays, " << t.hits << " Embree hits, " << t.agree << " agree, " << t.near_edge
                  << " excused near an edge, " << t.duplicate << " duplicate-triangle ties, "
                  << t.failures << " failures; over agreeing hits: max rel t diff " << t.max_rel_t
                  << " (" << t.max_strict_rel_t << " without the floor), max |du|,|dv| "
                  << t.max_d_uv << " (" << t.uv_off << " hits over 1e-3), max hit point distance "
                  << t.max_d_pos << " x diagonal" << std::endl;
        CHECK(t.failures == 0);
        CHECK(t.hits > n / 20); // the ray set really hits the mesh
        CHECK(t.near_edge < n / 1000);
        // Barycentrics of agreeing hits: a swapped or wrong weight is off by ~0.5. Near-grazing
        // rays make them ill-conditioned (both ours and Embree's are off from a double-precision
        // reference by up to 3e-3 and 8e-3 on the knot), hence 0.02. Across the far slivers,
        // 2-5 float steps wide, the weights are quantized and differ on most hits, so only the
        // bound applies there; elsewhere fewer than 1% of hits may differ by over 1e-3.
        CHECK(t.max_d_uv < 0.02);
        if (std::string(name) != "far_slivers.ply") CHECK(t.uv_off < t.hits / 100);

        // Any hit against Embree, exactly. Segments end halfway to Embree's closest hit (must be
        // free) or past it (must be blocked), so tmax is exercised on both sides. Left out:
        // rays whose closest-hit comparison was excused near an edge (there the two intersectors
        // legitimately disagree on whether the edge is hit at all), and rays that start exactly
        // on a surface (t == 0): the segment [0, 0) is empty for Tandem, whose interval is
        // [tmin, tmax) as in pbrt, while Embree's [tnear, tfar] is closed.
        std::vector<gpu::Ray> shadow;
        for (std::size_t i = 0; i < n; ++i) {
            gpu::Ray r = rays[i];
            if (t.cls[i] == k_near_edge || (ref[i].prim != HIT_NONE && ref[i].t == 0.0f)) continue;
            if (ref[i].prim != HIT_NONE) r.dir.w = (i % 2 ? 0.5f : 1.5f) * ref[i].t;
            shadow.push_back(r);
        }
        Buffer<gpu::Ray> dshadow(*ctx, "shadow rays", shadow);
        Buffer<unsigned> docc(*ctx, "occluded", shadow.size());
        tracer.any(dbvh, dshadow, docc);
        const std::vector<unsigned> occ = docc.download();
        std::vector<unsigned> ref_occ;
        reference.occluded(shadow, ref_occ, 2, EmbreeMode::single);
        std::size_t occ_diff = 0, blocked = 0;
        for (std::size_t i = 0; i < shadow.size(); ++i) {
            if (occ[i] != ref_occ[i] && occ_diff < 5)
                std::cerr << "  shadow ray " << i << ": device " << occ[i] << ", Embree "
                          << ref_occ[i] << ", tmax " << shadow[i].dir.w << "\n";
            occ_diff += occ[i] != ref_occ[i];
            blocked += ref_occ[i];
        }
        std::cout << "[trace] " << name << " " << layout_name(bvh) << " " << kind
                  << " any-hit: " << shadow.size() << " rays, " << blocked << " occluded, "
                  << occ_diff << " differ from Embree" << std::endl;
        CHECK(occ_diff == 0);
        CHECK(shadow.size() >= n - n / 1000);

        // The interval's lower end: every fourth ray again, from just past Embree's first hit
        // (tmin = 1.001 t), against Embree with the same tnear: the next surface along it, or
        // none. Left out as above: rays excused near an edge, and rays that missed.
        std::vector<gpu::Ray> later;
        for (std::size_t i = 0; i < n; i += 4) {
            if (t.cls[i] == k_near_edge || ref[i].prim == HIT_NONE || !(ref[i].t > 0.0f)) continue;
            gpu::Ray r = rays[i];
            r.org.w = 1.001f * ref[i].t;
            later.push_back(r);
        }
        Buffer<gpu::Ray> dlater(*ctx, "rays from past the first hit", later);
        Buffer<gpu::Hit> dlater_hits(*ctx, "hits past the first", later.size());
        tracer.closest(dbvh, dlater, dlater_hits);
        std::vector<gpu::Hit> ref_later;
        reference.intersect(later, ref_later, 2, EmbreeMode::single);
        const Tally tl = compare_closest(mesh, later, dlater_hits.download(), ref_later);
        std::cout << "[trace] " << name << " " << layout_name(bvh) << " " << kind
                  << " past tmin: " << tl.rays << " rays, " << tl.hits << " Embree hits, "
                  << tl.near_edge << " excused near an edge, " << tl.failures << " failures"
                  << std::endl;
        CHECK(tl.failures == 0);
        CHECK(tl.hits > tl.rays / 20); // behind a surface lies another (a closed tube, a fan)
        CHECK(tl.near_edge < tl.rays / 1000 + 1);

        // Bitwise determinism: a second launch gives the same bytes.
        tracer.closest(dbvh, drays, dhits);
        CHECK(test::same_bytes(dev, dhits.download()));
        tracer.any(dbvh, dshadow, docc);
        CHECK(test::same_bytes(occ, docc.download()));
    }
}

/// The host's closest hit through `bvh`, in its layout (the shared traversal code).
gpu::Hit host_closest(const FlatBvh& bvh, const gpu::Ray& ray) {
    if (bvh.width == 8)
        return gpu::bvh8_intersect_closest(bvh.nodes8.data(), bvh.triangles.data(), ray, bvh.tri4);
    return bvh.width == 4
               ? gpu::bvh4_intersect_closest(bvh.nodes4.data(), bvh.triangles.data(), ray, bvh.tri4)
               : gpu::bvh_intersect_closest(bvh.nodes.data(), bvh.triangles.data(), ray);
}

} // namespace

TEST_SUITE("device") {
    TEST_CASE("trace BVH2: procedural knot, 131k triangles") { check_mesh("knot.ply", 2); }
    TEST_CASE("trace BVH2: degenerate and duplicate triangles") { check_mesh("degenerate.obj", 2); }
    TEST_CASE("trace BVH2: thin slivers offset 1e4 from the origin") { check_mesh("far_slivers.ply", 2); }
    TEST_CASE("trace BVH4: procedural knot, 131k triangles") { check_mesh("knot.ply", 4); }
    TEST_CASE("trace BVH4: degenerate and duplicate triangles") { check_mesh("degenerate.obj", 4); }
    TEST_CASE("trace BVH4: thin slivers offset 1e4 from the origin") { check_mesh("far_slivers.ply", 4); }
    TEST_CASE("trace BVH4, blocks of four: procedural knot") {
        check_mesh("knot.ply", 4, LeafFormat::tri4);
    }
    TEST_CASE("trace BVH8, blocks of four: procedural knot") {
        check_mesh("knot.ply", 8, LeafFormat::tri4);
    }
    TEST_CASE("trace BVH8: degenerate and duplicate triangles") {
        check_mesh("degenerate.obj", 8);
    }
    TEST_CASE("trace BVH8: thin slivers offset 1e4 from the origin") {
        check_mesh("far_slivers.ply", 8);
    }
    TEST_CASE("trace BVH4, blocks of four: degenerate and duplicate triangles") {
        check_mesh("degenerate.obj", 4, LeafFormat::tri4);
    }
    TEST_CASE("trace BVH4, blocks of four: thin slivers offset 1e4 from the origin") {
        check_mesh("far_slivers.ply", 4, LeafFormat::tri4);
    }

    TEST_CASE("trace: BVH2, BVH4 and BVH8, with records or blocks, and BVH8 with its prefetches, "
              "report identical hits, ties included") {
        TANDEM_REQUIRE_DEVICE(ctx);
        EmbreeDevice embree;
        Tracer tracer(*ctx, KernelLibrary::from_environment());
        Tracer prefetching(*ctx, KernelLibrary::from_environment(), /*analytic=*/false,
                           /*prefetch=*/true);
        for (const char* name : {"knot.ply", "degenerate.obj", "far_slivers.ply"}) {
            INFO(name);
            const TriangleMesh mesh = load_mesh(mesh_path(name));
            const DeviceBvh layouts[5] = {
                DeviceBvh(*ctx, build_bvh(embree, mesh, 2)),
                DeviceBvh(*ctx, build_bvh(embree, mesh, 4)),
                DeviceBvh(*ctx, build_bvh(embree, mesh, 4, LeafFormat::tri4)),
                DeviceBvh(*ctx, build_bvh(embree, mesh, 8)),
                DeviceBvh(*ctx, build_bvh(embree, mesh, 8, LeafFormat::tri4))};
            for (const std::vector<gpu::Ray>& rays : {make_camera_rays(mesh.bounds(), 1024, 1024),
                                                      make_random_rays(mesh.bounds(), 1 << 20, 3)}) {
                Buffer<gpu::Ray> drays(*ctx, "rays", rays);
                // 5 and 6: the eight-wide layouts again, with BVH_PREFETCH, on the knot alone (a
                // mesh of the size it is for; the code around the prefetches is what is checked)
                const int variants = std::string(name) == "knot.ply" ? 7 : 5;
                std::vector<gpu::Hit> hits[7];
                std::vector<unsigned> occ[7];
                for (int k = 0; k < variants; ++k) {
                    Buffer<gpu::Hit> dhits(*ctx, "hits", rays.size());
                    Buffer<unsigned> docc(*ctx, "occluded", rays.size());
                    Tracer& t = k < 5 ? tracer : prefetching;
                    const DeviceBvh& layout = layouts[k < 5 ? k : k - 2];
                    t.closest(layout, drays, dhits);
                    t.any(layout, drays, docc);
                    hits[k] = dhits.download();
                    occ[k] = docc.download();
                }
                for (int k = 1; k < variants; ++k) {
                    INFO("layout " << k << " against BVH2");
                    CHECK(test::same_bytes(hits[0], hits[k]));
                    CHECK(test::same_bytes(occ[0], occ[k]));
                }
            }
        }
    }

    TEST_CASE("trace: packets of eight rays give each ray its one-ray hit, ties and bad rays "
              "included") {
        TANDEM_REQUIRE_DEVICE(ctx);
        EmbreeDevice embree;
        Tracer tracer(*ctx, KernelLibrary::from_environment());
        auto ray = [](glm::vec3 o, glm::vec3 d, float tmin, float tmax) {
            gpu::Ray r;
            r.org = {o.x, o.y, o.z, tmin};
            r.dir = {d.x, d.y, d.z, tmax};
            return r;
        };
        for (const std::string name : {"knot.ply", "degenerate.obj", "far_slivers.ply"}) {
            INFO(name);
            const TriangleMesh mesh = load_mesh(mesh_path(name.c_str()));
            const DeviceBvh bvh(*ctx, build_bvh(embree, mesh, 8, LeafFormat::tri4));
            const Bounds b = mesh.bounds();
            // Rays at vertices and edge midpoints, where neighbours tie in t (the lowest id
            // wins), from points around the mesh, eight to a packet from eight origins; then
            // rays a packet cannot be trusted with: NaN and infinite components, an empty or a
            // NaN interval, a zero direction, tmin past the first hit. 8k + 5 of them, so the
            // last packet is not full.
            const std::vector<gpu::Ray> around = make_random_rays(b, 8 * 4096, 17);
            std::vector<gpu::Ray> odd;
            for (std::size_t i = 0; i < around.size(); ++i) {
                const glm::uvec3 t = mesh.triangles[(i * 7919) % mesh.triangles.size()];
                const glm::vec3 o(around[i].org.x, around[i].org.y, around[i].org.z);
                const glm::vec3 target = i % 2 ? mesh.positions[t.x]
                                               : 0.5f * (mesh.positions[t.y] + mesh.positions[t.z]);
                odd.push_back(ray(o, target - o, i % 3 == 0 ? 0.5f : 0.0f, INFINITY));
            }
            const float nan = std::nanf("");
            const glm::vec3 c = b.center();
            odd.push_back(ray(c, {nan, 1, 0}, 0, INFINITY));
            odd.push_back(ray({INFINITY, 0, 0}, {1, 0, 0}, 0, INFINITY));
            odd.push_back(ray(c, {0, 0, 1}, 2, 1));
            odd.push_back(ray(c, {0, 0, 0}, 0, INFINITY));
            odd.push_back(ray(c, {0, 1, 0}, nan, INFINITY));
            const std::vector<gpu::Ray> sets[] = {make_camera_rays(b, 512, 512),
                                                  make_random_rays(b, 1 << 18, 3), odd};
            for (const std::vector<gpu::Ray>& rays : sets) {
                Buffer<gpu::Ray> drays(*ctx, "rays", rays);
                Buffer<gpu::Hit> one(*ctx, "one-ray hits", rays.size());
                Buffer<gpu::Hit> packets(*ctx, "packet hits", rays.size());
                tracer.closest(bvh, drays, one);
                tracer.closest_packets(bvh, drays, packets);
                const std::vector<gpu::Hit> a = one.download(), p = packets.download();
                std::size_t hits = 0;
                for (const gpu::Hit& h : a)
                    hits += h.prim != HIT_NONE;
                CHECK(hits > rays.size() / 10);
                std::size_t differ = 0;
                for (std::size_t i = 0; i < a.size(); ++i)
                    if (std::memcmp(&a[i], &p[i], sizeof a[i]) != 0 && differ++ < 3)
                        std::cerr << "  ray " << i << " of " << a.size() << ": one-ray prim "
                                  << a[i].prim << " t " << a[i].t << " u " << a[i].u << " v "
                                  << a[i].v << "; packet prim " << p[i].prim << " t " << p[i].t
                                  << " u " << p[i].u << " v " << p[i].v << "\n";
                CHECK(differ == 0);
            }
        }
        const DeviceBvh records(*ctx, build_bvh(embree, load_mesh(mesh_path("knot_small.obj")), 8));
        Buffer<gpu::Ray> drays(*ctx, "rays", std::vector<gpu::Ray>(8));
        Buffer<gpu::Hit> dhits(*ctx, "hits", 8);
        CHECK_THROWS_WITH_AS(tracer.closest_packets(records, drays, dhits),
                             doctest::Contains("eight-wide tree of blocks"), Error);
    }

    TEST_CASE("trace: analytic spheres and disks on the device give the host's hits") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const TriangleMesh mesh = test::mesh_with_analytic_shapes();
        EmbreeDevice embree;
        Tracer tracer(*ctx, KernelLibrary::from_environment(), /*analytic=*/true);
        const std::vector<gpu::Ray> rays = make_random_rays(mesh.bounds(), 1 << 16, 5);
        Buffer<gpu::Ray> drays(*ctx, "rays", rays);
        for (int width : {2, 4, 8}) {
            const FlatBvh bvh = build_bvh(embree, mesh, width);
            const DeviceBvh dbvh(*ctx, bvh);
            Buffer<gpu::Hit> dhits(*ctx, "hits", rays.size());
            Buffer<unsigned> docc(*ctx, "occluded", rays.size());
            tracer.closest(dbvh, drays, dhits);
            tracer.any(dbvh, drays, docc);
            const std::vector<gpu::Hit> dev = dhits.download();
            const std::vector<unsigned> occ = docc.download();
            std::size_t same_prim = 0, same_bits = 0, same_occ = 0, sphere_hits = 0, disk_hits = 0;
            const std::size_t first_disk = mesh.triangle_count() + mesh.spheres.size();
            for (std::size_t i = 0; i < rays.size(); ++i) {
                const gpu::Hit h = host_closest(bvh, rays[i]);
                same_prim += h.prim == dev[i].prim;
                same_bits += std::memcmp(&h, &dev[i], sizeof h) == 0;
                same_occ += occ[i] == (h.prim != HIT_NONE ? 1u : 0u);
                sphere_hits += h.prim != HIT_NONE && h.prim >= mesh.triangle_count() && h.prim < first_disk;
                disk_hits += h.prim != HIT_NONE && h.prim >= first_disk;
            }
            INFO("BVH" << width << ": " << sphere_hits << " sphere hits, " << disk_hits << " disk hits");
            CHECK(sphere_hits > 3000);
            CHECK(disk_hits > 300);
            CHECK(same_prim == rays.size());
            CHECK(same_occ == rays.size());
            if (ctx->device().correctly_rounded_divide_sqrt) CHECK(same_bits == rays.size());
        }
    }

    // The same source; on PoCL for x86 the eight-wide loops hold the nearest child back
    // (BVH8_HOLD_NEAREST) where the host pushes every child, so this also checks that both forms
    // find the same hits.
    TEST_CASE("trace: device and host run the same traversal code to the same hits") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const TriangleMesh mesh = load_mesh(mesh_path("knot.ply"));
        EmbreeDevice embree;
        Tracer tracer(*ctx, KernelLibrary::from_environment());
        const std::vector<gpu::Ray> rays = make_random_rays(mesh.bounds(), 1 << 16, 5);
        Buffer<gpu::Ray> drays(*ctx, "rays", rays);
        for (int width : {2, 4, 5, 8, 9}) { // 5, 9: four- and eight-wide, blocks of four triangles
            const FlatBvh bvh = build_bvh(embree, mesh, width & ~1,
                                          width % 2 ? LeafFormat::tri4 : LeafFormat::records);
            const DeviceBvh dbvh(*ctx, bvh);
            Buffer<gpu::Hit> dhits(*ctx, "hits", rays.size());
            tracer.closest(dbvh, drays, dhits);
            const std::vector<gpu::Hit> dev = dhits.download();
            std::size_t same_prim = 0, same_bits = 0;
            for (std::size_t i = 0; i < rays.size(); ++i) {
                const gpu::Hit h = host_closest(bvh, rays[i]);
                same_prim += h.prim == dev[i].prim;
                same_bits += std::memcmp(&h, &dev[i], sizeof h) == 0;
            }
            std::cout << "[trace] " << layout_name(bvh) << " host/device parity: " << same_prim
                      << " / " << rays.size() << " same primitive, " << same_bits
                      << " bitwise identical" << std::endl;
            // IEEE single precision without contraction on both sides: the same bits wherever
            // the device divides correctly rounded (base_build_options asks for it when the
            // device offers it; PoCL does). Elsewhere OpenCL allows 2.5 ulp: compare hits only.
            CHECK(same_prim == rays.size());
            if (ctx->device().correctly_rounded_divide_sqrt) CHECK(same_bits == rays.size());
        }
    }
}
