// Trace benchmark: the same rays through the OpenCL kernels and through Embree, side by side.
#include "core/trace_bench.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <sstream>
#include <thread>

#include "core/embree_scene.h"
#include "core/rays.h"
#include "core/tracer.h"

namespace tandem {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

struct RaySet {
    const char* name;
    const char* query;
    std::vector<gpu::Ray> rays;
};

} // namespace

TraceBenchResult run_trace_bench(const TraceBenchOptions& opt) {
    auto say = [&](const std::string& what) {
        if (opt.progress) std::cerr << "[bench trace] " << what << std::endl;
    };
    TraceBenchResult res;
    const int threads =
        opt.threads > 0 ? opt.threads : std::max(1u, std::thread::hardware_concurrency());
    res.embree_threads = threads;

    say("loading " + opt.mesh);
    const TriangleMesh mesh = load_mesh(opt.mesh);
    res.mesh = opt.mesh;
    res.triangles = mesh.triangle_count();

    EmbreeDevice embree("threads=" + std::to_string(threads));
    say("building BVH (" + std::to_string(res.triangles) + " triangles)");
    auto t0 = std::chrono::steady_clock::now();
    const FlatBvh bvh = build_bvh(embree, mesh, opt.bvh_width);
    res.bvh_build_s = seconds_since(t0);
    res.bvh_nodes = bvh.node_count();
    res.bvh_width = bvh.width;
    res.bvh_depth = bvh.depth;
    const EmbreeScene reference(embree, mesh, /*robust=*/false);

    Context ctx = Context::create(opt.device);
    res.device = ctx.device().name;
    say("compiling kernels for " + res.device);
    Tracer tracer(ctx, KernelLibrary::from_environment());
    const DeviceBvh dbvh(ctx, bvh);
    const std::vector<StageTime> upload = ctx.stage_times();
    res.bvh_upload_s =
        stage_seconds(upload, "upload bvh nodes") + stage_seconds(upload, "upload bvh triangles");

    const Bounds bounds = mesh.bounds();
    const int side = std::max(1, static_cast<int>(std::lround(std::sqrt(double(opt.rays)))));
    std::vector<RaySet> sets;
    sets.push_back({"coherent", "closest", make_camera_rays(bounds, side, side)});
    sets.push_back({"incoherent", "closest", make_random_rays(bounds, opt.rays, 1)});
    sets.push_back({"shadow", "any", make_shadow_rays(bounds, opt.rays, 2)});
    res.rays = opt.rays;

    for (RaySet& set : sets) {
        say(std::string("tracing ") + set.name + " rays");
        const bool closest = std::string(set.query) == "closest";
        const std::size_t n = set.rays.size();
        TraceBenchRow row;
        row.name = set.name;
        row.query = set.query;

        // Device: one untimed warm-up launch, then the best kernel time of `repeats` launches.
        ctx.stage_times();
        Buffer<gpu::Ray> rays(ctx, std::string(set.name) + " rays", set.rays, CL_MEM_READ_ONLY);
        Buffer<gpu::Hit> hits(ctx, "hits", closest ? n : 1);
        Buffer<unsigned> occ(ctx, "occluded", closest ? 1 : n);
        row.upload_s = stage_seconds(ctx.stage_times(), "upload " + std::string(set.name) + " rays");
        double best = 1e30;
        for (int r = 0; r <= opt.repeats; ++r) {
            closest ? tracer.closest(dbvh, rays, hits) : tracer.any(dbvh, rays, occ);
            const double s = stage_seconds(ctx.stage_times(),
                                           closest ? Tracer::k_stage_closest : Tracer::k_stage_any);
            if (r > 0) best = std::min(best, s);
        }
        row.tandem_mrays_s = n / best * 1e-6;
        std::vector<gpu::Hit> dev_hits;
        std::vector<unsigned> dev_occ;
        if (closest) dev_hits = hits.download(); else dev_occ = occ.download();
        row.download_s = stage_seconds(ctx.stage_times(), closest ? "download hits" : "download occluded");

        // Embree: every mode, best wall time of `repeats` each.
        std::vector<gpu::Hit> ref_hits;
        std::vector<unsigned> ref_occ;
        double embree_best = 1e30;
        for (EmbreeMode mode : {EmbreeMode::single, EmbreeMode::packet8, EmbreeMode::packet16}) {
            for (int r = 0; r <= opt.repeats; ++r) {
                t0 = std::chrono::steady_clock::now();
                closest ? reference.intersect(set.rays, ref_hits, threads, mode)
                        : reference.occluded(set.rays, ref_occ, threads, mode);
                const double s = seconds_since(t0);
                if (r > 0 && s < embree_best) {
                    embree_best = s;
                    row.embree_mode = embree_mode_name(mode);
                }
            }
        }
        row.embree_mrays_s = n / embree_best * 1e-6;
        row.ratio = row.tandem_mrays_s / row.embree_mrays_s;
        for (std::size_t i = 0; i < n; ++i)
            row.mismatches += closest ? ((dev_hits[i].prim == HIT_NONE) != (ref_hits[i].prim == HIT_NONE))
                                      : (dev_occ[i] != ref_occ[i]);
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
    j["bvh"] = {{"width", bvh_width}, {"nodes", bvh_nodes}, {"depth", bvh_depth}, {"build_s", bvh_build_s},
                {"upload_s", bvh_upload_s}};
    for (const TraceBenchRow& r : rows)
        j[r.name] = {{"query", r.query},
                     {"tandem_mrays_s", r.tandem_mrays_s},
                     {"embree_mrays_s", r.embree_mrays_s},
                     {"ratio", r.ratio},
                     {"embree_mode", r.embree_mode},
                     {"upload_s", r.upload_s},
                     {"download_s", r.download_s},
                     {"hit_mismatches", r.mismatches}};
    return j;
}

std::string TraceBenchResult::to_table() const {
    std::ostringstream out;
    char line[256];
    out << "mesh: " << mesh << " (" << triangles << " triangles; BVH" << bvh_width << " " << bvh_nodes
        << " nodes, depth " << bvh_depth << ", built in " << bvh_build_s << " s)\n";
    out << "device: " << device << "; Embree on " << embree_threads << " threads; " << rays
        << " rays per set\n\n";
    std::snprintf(line, sizeof line, "%-11s %-8s %14s %14s %7s  %-15s %10s %12s %10s\n", "rays",
                  "query", "tandem Mray/s", "embree Mray/s", "ratio", "embree mode",
                  "upload ms", "download ms", "mismatch");
    out << line;
    for (const TraceBenchRow& r : rows) {
        std::snprintf(line, sizeof line, "%-11s %-8s %14.2f %14.2f %7.3f  %-15s %10.2f %12.2f %10zu\n",
                      r.name.c_str(), r.query.c_str(), r.tandem_mrays_s, r.embree_mrays_s, r.ratio,
                      r.embree_mode.c_str(), r.upload_s * 1e3, r.download_s * 1e3, r.mismatches);
        out << line;
    }
    return out.str();
}

} // namespace tandem
