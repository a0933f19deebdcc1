// Trace benchmark: the same rays through the OpenCL kernels (every BVH layout) and through Embree
// (every entry point), interleaved repetition by repetition so machine noise hits all alike.
#include "bench/trace_bench.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <memory>
#include <sstream>
#include <thread>

#include "bench/embree_scene.h"
#include "bench/rays.h"
#include "bench/tracer.h"
#include "core/render/policy.h"

namespace tandem {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

struct RaySet {
    const char* name;
    bool closest; ///< closest hit, else any hit
    std::vector<gpu::Ray> rays;
};

/// The device layouts timed side by side: the BVH's width, its leaves' format, whether the
/// eight-wide traversal prefetches (BVH_PREFETCH), and whether closest hits are traced in packets
/// of eight rays (CAMERA_PACKETS' traversal). The last two variants are the CPUs' layout again
/// with each, so that one run measures what they buy.
struct Layout {
    const char* name;
    int width;
    LeafFormat leaves;
    bool prefetch;
    bool packets; ///< closest hits in packets of eight rays (Tracer::closest_packets)
};
constexpr Layout k_layouts[] = {
    {"bvh2", 2, LeafFormat::records, false, false},
    {"bvh4", 4, LeafFormat::records, false, false},
    {"bvh4_tri4", 4, LeafFormat::tri4, false, false},
    {"bvh8", 8, LeafFormat::records, false, false},
    {"bvh8_tri4", 8, LeafFormat::tri4, false, false},
    {"bvh8_tri4_pf", 8, LeafFormat::tri4, true, false},
    // any-hit queries have no packets: the shadow rays' column repeats bvh8_tri4's traversal
    {"bvh8_tri4_pk", 8, LeafFormat::tri4, false, true}};

} // namespace

TraceBenchResult run_trace_bench(const TraceBenchOptions& opt) {
    auto say = [&](const std::string& what) {
        if (opt.progress) std::cerr << "[bench trace] " << what << std::endl;
    };
    TraceBenchResult res;
    const int threads =
        opt.threads > 0 ? opt.threads : std::max(1u, std::thread::hardware_concurrency());
    res.embree_threads = threads;

    // Step 1: mesh, every BVH layout, Embree's scene (default flags: its fastest mode).
    say("loading " + opt.mesh);
    const TriangleMesh mesh = load_mesh(opt.mesh);
    res.mesh = opt.mesh;
    res.triangles = mesh.triangle_count();
    Context ctx = Context::create(opt.device, opt.tuning);
    ctx.set_stage_timing(true);
    res.device = ctx.device().name;
    res.bvh_width = opt.bvh_width ? opt.bvh_width : preferred_bvh_width(ctx.device());
    const LeafFormat head_leaves =
        preferred_leaf_format(ctx.device(), mesh.triangle_count(), res.bvh_width);
    const bool head_prefetch = ctx.tuning().bvh_prefetch.value_or(
        prefers_prefetch(ctx.device(), mesh.triangle_count(), res.bvh_width));
    std::size_t head = 0; // the headline layout: the device's preferred (preferred_bvh_width; on
                          // GPUs renders of meshes take 8: forward_bvh_width)

    EmbreeDevice embree("threads=" + std::to_string(threads));
    say("building BVHs (" + std::to_string(res.triangles) + " triangles)");
    // One tree per layout of its own; the prefetching variant traces the tree of blocks of the
    // same width (tree[v]: the layout whose tree layout v traces).
    std::vector<FlatBvh> bvhs(std::size(k_layouts));
    std::vector<std::size_t> tree(std::size(k_layouts));
    const bool repack = ctx.tuning().bvh_repack;
    for (std::size_t v = 0; v < std::size(k_layouts); ++v) {
        const Layout& layout = k_layouts[v];
        const bool head_tree = layout.width == res.bvh_width && layout.leaves == head_leaves;
        if (layout.prefetch || layout.packets) {
            const auto same_tree = [&](const Layout& l) {
                return l.width == layout.width && l.leaves == layout.leaves;
            };
            tree[v] =
                static_cast<std::size_t>(std::find_if(k_layouts, k_layouts + v, same_tree) - k_layouts);
            if (head_tree && head_prefetch && layout.prefetch) head = v;
            continue;
        }
        const auto t0 = std::chrono::steady_clock::now();
        bvhs[v] = build_bvh(embree, mesh, layout.width, layout.leaves, repack);
        tree[v] = v;
        res.bvh_nodes.emplace_back(layout.name, bvhs[v].node_count());
        if (head_tree) {
            res.bvh_build_s = seconds_since(t0);
            head = v;
        }
    }
    res.layout = k_layouts[head].name;
    res.prefetch = k_layouts[head].prefetch;
    const EmbreeScene reference(embree, mesh, /*robust=*/false);

    say("compiling kernels for " + res.device);
    Tracer plain(ctx, KernelLibrary::from_tuning(opt.tuning));
    Tracer prefetching(ctx, KernelLibrary::from_tuning(opt.tuning), /*analytic=*/false,
                       /*prefetch=*/true);
    auto tracer = [&](std::size_t v) -> Tracer& {
        return k_layouts[v].prefetch ? prefetching : plain;
    };
    std::vector<std::unique_ptr<DeviceBvh>> uploaded(std::size(k_layouts));
    for (std::size_t v = 0; v < std::size(k_layouts); ++v) {
        if (tree[v] != v) continue;
        ctx.stage_times();
        uploaded[v] = std::make_unique<DeviceBvh>(ctx, bvhs[v]);
        const std::vector<StageTime> upload = ctx.stage_times();
        if (v == tree[head])
            res.bvh_upload_s = stage_seconds(upload, "upload bvh nodes") +
                               stage_seconds(upload, "upload bvh triangles");
    }
    std::vector<const DeviceBvh*> dbvhs(std::size(k_layouts));
    for (std::size_t v = 0; v < std::size(k_layouts); ++v) dbvhs[v] = uploaded[tree[v]].get();
    auto closest = [&](std::size_t v, const Buffer<gpu::Ray>& rays, Buffer<gpu::Hit>& hits) {
        k_layouts[v].packets ? plain.closest_packets(*dbvhs[v], rays, hits)
                             : tracer(v).closest(*dbvhs[v], rays, hits);
    };

    // Step 2: the ray sets.
    const Bounds bounds = mesh.bounds();
    // The camera image is the smallest square of at least N pixels, cut to N rays (scanlines).
    const int side = static_cast<int>(std::ceil(std::sqrt(double(opt.rays))));
    std::vector<gpu::Ray> camera = make_camera_rays(bounds, side, side);
    camera.resize(opt.rays);
    std::vector<RaySet> sets;
    sets.push_back({"coherent", true, std::move(camera)});
    sets.push_back({"incoherent", true, make_random_rays(bounds, opt.rays, 1)});
    sets.push_back({"shadow", false, make_shadow_rays(bounds, opt.rays, 2)});
    res.rays = opt.rays;

    // Step 3: every variant once untimed (warm-up, JIT), then `repeats` interleaved rounds.
    for (const RaySet& set : sets) {
        say(std::string("tracing ") + set.name + " rays");
        const std::size_t n = set.rays.size();
        TraceBenchRow row;
        row.name = set.name;
        row.query = set.closest ? "closest" : "any";
        ctx.stage_times();
        const std::string ray_buffer = std::string(set.name) + " rays";
        Buffer<gpu::Ray> rays(ctx, ray_buffer, set.rays, CL_MEM_READ_ONLY);
        Buffer<gpu::Hit> hits(ctx, "hits", set.closest ? n : 1);
        Buffer<unsigned> occ(ctx, "occluded", set.closest ? 1 : n);
        row.upload_s = stage_seconds(ctx.stage_times(), "upload " + ray_buffer);

        const EmbreeMode modes[] = {EmbreeMode::single, EmbreeMode::packet8, EmbreeMode::packet16};
        for (const Layout& layout : k_layouts)
            row.layouts.push_back({layout.name, 0.0});
        for (EmbreeMode mode : modes) row.embree_modes.push_back({embree_mode_name(mode, set.closest), 0.0});
        std::vector<gpu::Hit> ref_hits;
        std::vector<unsigned> ref_occ;
        for (int round = 0; round <= opt.repeats; ++round) {
            for (std::size_t v = 0; v < dbvhs.size(); ++v) {
                set.closest ? closest(v, rays, hits) : tracer(v).any(*dbvhs[v], rays, occ);
                const double s = stage_seconds(
                    ctx.stage_times(), set.closest ? Tracer::k_stage_closest : Tracer::k_stage_any);
                if (round > 0) row.layouts[v].mrays_s = std::max(row.layouts[v].mrays_s, n / s * 1e-6);
            }
            for (std::size_t m = 0; m < std::size(modes); ++m) {
                const auto t0 = std::chrono::steady_clock::now();
                set.closest ? reference.intersect(set.rays, ref_hits, threads, modes[m])
                            : reference.occluded(set.rays, ref_occ, threads, modes[m]);
                const double s = seconds_since(t0);
                if (round > 0)
                    row.embree_modes[m].mrays_s = std::max(row.embree_modes[m].mrays_s, n / s * 1e-6);
            }
        }

        // Step 4: every layout's results against the headline layout's, bit for bit.
        std::vector<std::vector<gpu::Hit>> layout_hits(dbvhs.size());
        std::vector<std::vector<unsigned>> layout_occ(dbvhs.size());
        for (std::size_t v = 0; v < dbvhs.size(); ++v) {
            if (set.closest) {
                closest(v, rays, hits);
                layout_hits[v] = hits.download();
            } else {
                tracer(v).any(*dbvhs[v], rays, occ);
                layout_occ[v] = occ.download();
            }
        }
        std::vector<char> differs(n, 0);
        for (std::size_t v = 0; v < dbvhs.size(); ++v)
            for (std::size_t i = 0; i < n; ++i)
                differs[i] |= set.closest ? std::memcmp(&layout_hits[v][i], &layout_hits[head][i],
                                                        sizeof(gpu::Hit)) != 0
                                          : layout_occ[v][i] != layout_occ[head][i];
        row.layout_mismatches =
            static_cast<std::size_t>(std::count(differs.begin(), differs.end(), 1));
        ctx.stage_times(); // Step 5 times one download of its own

        // Step 5: headline numbers, and a hit/miss sanity check of the headline layout.
        set.closest ? tracer(head).closest(*dbvhs[head], rays, hits)
                    : tracer(head).any(*dbvhs[head], rays, occ);
        row.tandem_mrays_s = row.layouts[head].mrays_s;
        const auto best = std::max_element(
            row.embree_modes.begin(), row.embree_modes.end(),
            [](const TraceTiming& a, const TraceTiming& b) { return a.mrays_s < b.mrays_s; });
        row.embree_mrays_s = best->mrays_s;
        row.embree_mode = best->name;
        row.ratio = row.tandem_mrays_s / row.embree_mrays_s;
        if (set.closest) {
            const std::vector<gpu::Hit> dev = hits.download();
            for (std::size_t i = 0; i < n; ++i)
                row.mismatches += (dev[i].prim == HIT_NONE) != (ref_hits[i].prim == HIT_NONE);
        } else {
            const std::vector<unsigned> dev = occ.download();
            for (std::size_t i = 0; i < n; ++i) row.mismatches += dev[i] != ref_occ[i];
        }
        row.download_s = stage_seconds(ctx.stage_times(), set.closest ? "download hits" : "download occluded");
        res.rows.push_back(row);
    }
    return res;
}

nlohmann::json TraceBenchResult::to_json() const {
    nlohmann::json j;
    j["mesh"] = mesh;
    j["triangles"] = triangles;
    j["device"] = device;
    j["rays"] = rays;
    j["embree_threads"] = embree_threads;
    j["bvh"] = {{"width", bvh_width},
                {"layout", layout},
                {"prefetch", prefetch},
                {"build_s", bvh_build_s},
                {"upload_s", bvh_upload_s}};
    for (const auto& [name, nodes] : bvh_nodes)
        j["bvh"]["nodes_" + name] = nodes;
    for (const TraceBenchRow& r : rows) {
        nlohmann::json row = {{"query", r.query},
                              {"tandem_mrays_s", r.tandem_mrays_s},
                              {"embree_mrays_s", r.embree_mrays_s},
                              {"ratio", r.ratio},
                              {"embree_mode", r.embree_mode},
                              {"upload_s", r.upload_s},
                              {"download_s", r.download_s},
                              {"hit_mismatches", r.mismatches},
                              {"layout_mismatches", r.layout_mismatches}};
        for (const TraceTiming& t : r.layouts) row["tandem_" + t.name + "_mrays_s"] = t.mrays_s;
        for (const TraceTiming& t : r.embree_modes) row["embree_" + t.name + "_mrays_s"] = t.mrays_s;
        j[r.name] = row;
    }
    return j;
}

std::string TraceBenchResult::to_table() const {
    std::ostringstream out;
    char line[512];
    out << "mesh: " << mesh << " (" << triangles << " triangles)\n";
    out << "device: " << device << "; headline layout " << layout << " (built in " << bvh_build_s
        << " s); BVH_PREFETCH=" << (prefetch ? 1 : 0) << "; Embree on " << embree_threads
        << " threads; " << rays << " rays per set\n\n";
    std::snprintf(
        line, sizeof line,
        "%-11s %-8s %10s %10s %10s %10s %10s %10s %10s %13s %14s %14s %7s %9s %9s %8s %8s\n",
        "rays", "query", "bvh2", "bvh4", "bvh4 tri4", "bvh8", "bvh8 tri4", "+prefetch", "+packets",
        "embree 1", "embree 8", "embree 16", "ratio", "upload", "download", "mismatch", "layouts");
    out << line;
    std::snprintf(
        line, sizeof line,
        "%-11s %-8s %10s %10s %10s %10s %10s %10s %10s %13s %14s %14s %7s %9s %9s %8s %8s\n", "",
        "", "Mray/s", "Mray/s", "Mray/s", "Mray/s", "Mray/s", "Mray/s", "Mray/s", "Mray/s",
        "Mray/s", "Mray/s", "", "ms", "ms", "", "differ");
    out << line;
    for (const TraceBenchRow& r : rows) {
        std::snprintf(
            line, sizeof line,
            "%-11s %-8s %10.2f %10.2f %10.2f %10.2f %10.2f %10.2f %10.2f %13.2f %14.2f %14.2f "
            "%7.3f %9.2f %9.2f %8zu %8zu\n",
            r.name.c_str(), r.query.c_str(), r.layouts[0].mrays_s, r.layouts[1].mrays_s,
            r.layouts[2].mrays_s, r.layouts[3].mrays_s, r.layouts[4].mrays_s, r.layouts[5].mrays_s,
            r.layouts[6].mrays_s, r.embree_modes[0].mrays_s, r.embree_modes[1].mrays_s,
            r.embree_modes[2].mrays_s, r.ratio, r.upload_s * 1e3, r.download_s * 1e3, r.mismatches,
            r.layout_mismatches);
        out << line;
    }
    out << "\nratio = headline layout / fastest Embree entry point (rtcIntersect1/8/16 or "
           "rtcOccluded1/8/16). +prefetch = bvh8 tri4 with BVH_PREFETCH\n(the headline where "
           "BVH_PREFETCH=1 above). +packets = bvh8 tri4 tracing closest hits in packets of eight\n"
           "consecutive rays (any hits: one ray at a time, as bvh8 tri4). Device rates count "
           "kernel "
           "time only; transfers are listed\nseparately. Embree rates are wall time.\n";
    return out.str();
}

} // namespace tandem
