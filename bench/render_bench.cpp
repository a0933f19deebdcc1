// Render benchmark. Throughput: samples/s of the path tracer at a few resolutions, after an untimed
// warm-up render (PoCL compiles the kernel at its first launch). Convergence: renders at spp = 1,
// 2, 4, ... with independent seeds against a high-spp reference of the same scene and resolution;
// RMSE against wall time on a log-log scale should have slope -1/2 for an unbiased Monte Carlo
// estimator whose cost is linear in spp.
#include "bench/render_bench.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <memory>
#include <sstream>

#include "core/inverse/session.h"
#include "core/render/passes.h"
#include "runtime/error.h"

namespace tandem {

namespace {

/// Best of the repeats: other load on the machine only ever adds time.
double least(const std::vector<double>& v) {
    return *std::min_element(v.begin(), v.end());
}

/// Least-squares slope of y against x; NaN (null in the JSON, "n/a" in the table) with fewer
/// than two distinct x, where a line has no slope to fit.
double fit_slope(const std::vector<double>& x, const std::vector<double>& y) {
    const double n = double(x.size());
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
        sx += x[i];
        sy += y[i];
        sxx += x[i] * x[i];
        sxy += x[i] * y[i];
    }
    const double den = n * sxx - sx * sx;
    return den != 0 ? (n * sxy - sx * sy) / den : std::numeric_limits<double>::quiet_NaN();
}

SceneDesc resized(SceneDesc desc, int size) {
    desc.camera().width = desc.camera().height = size;
    return desc;
}

/// The scene at a square resolution, with a renderer that has rendered once (untimed warm-up).
struct Setup {
    Session session;
    const RenderScene& scene;
    DeviceScene* device;

    Setup(Context& ctx, const KernelLibrary& lib, const SceneDesc& desc, int size,
          int det_math = 1)
        : session(ctx, lib, build_render_scene(resized(desc, size)), options(det_math)),
          scene(session.scene()), device(&session.device_scene()) {
        RenderOptions warm;
        warm.spp = 1;
        warm.seed = 0xFFFFFFFFu;
        render(warm);
    }
    Setup(const Setup&) = delete;
    Setup& operator=(const Setup&) = delete;
    /// The scene's own parameter values.
    RenderResult render(const RenderOptions& o) { return session.render_image(o); }
    static SessionOptions options(int det_math) {
        SessionOptions so;
        so.kernels = SessionOptions::Kernels::forward;
        so.flags = {{"DET_MATH", det_math}};
        return so;
    }
};

constexpr double k_rel_eps = 0.01; ///< relative MSE: (x - ref)^2 / (ref^2 + eps)

} // namespace

RenderBenchResult run_render_bench(const RenderBenchOptions& opt) {
    const auto start = std::chrono::steady_clock::now();
    auto say = [&](const std::string& what) {
        if (opt.progress) std::cerr << "[bench render] " << what << std::endl;
    };
    if (opt.reference_spp < 2) throw Error("bench render: --ref-spp must be at least 2");
    const int max_spp = opt.max_spp > 0 ? opt.max_spp : std::max(1, opt.reference_spp / 16);
    if (max_spp >= opt.reference_spp)
        throw Error("bench render: --max-spp must be below the reference spp");

    RenderBenchResult res;
    res.scene = opt.scene;
    res.size = opt.size;
    res.reference_spp = opt.reference_spp;
    res.repeats = opt.repeats;
    say("loading " + opt.scene);
    const SceneDesc desc = load_scene(opt.scene);
    Context ctx = Context::create(opt.device, opt.tuning);
    ctx.set_stage_timing(true); // kernel_seconds
    res.device = ctx.device().name;
    const KernelLibrary lib = KernelLibrary::from_tuning(opt.tuning);

    // Step 1: throughput. Seed 0 at every size.
    for (int size : opt.throughput_sizes) {
        say("throughput " + std::to_string(size) + "x" + std::to_string(size) + ": warm-up");
        Setup setup(ctx, lib, desc, size);
        say("throughput " + std::to_string(size) + "x" + std::to_string(size) + ", " +
            std::to_string(opt.throughput_spp) + " spp");
        RenderOptions o;
        o.spp = opt.throughput_spp;
        o.seed = 0;
        const RenderResult r = setup.render(o);
        res.nan_guards += r.nan_guards;
        RenderThroughput t;
        t.width = r.width;
        t.height = r.height;
        t.spp = r.spp;
        t.seconds = r.seconds;
        t.kernel_seconds = r.kernel_seconds;
        const double samples = double(r.width) * r.height * r.spp;
        t.samples_per_second = samples / r.seconds;
        t.kernel_samples_per_second = samples / r.kernel_seconds;
        res.throughput.push_back(t);
    }

    // Step 2: the cost of the deterministic transcendentals, both variants interleaved.
    {
        say("deterministic math against the built-ins, " + std::to_string(opt.size) + "x" +
            std::to_string(opt.size));
        Setup det(ctx, lib, desc, opt.size, 1), builtin(ctx, lib, desc, opt.size, 0);
        std::vector<double> t_det, t_builtin;
        RenderOptions o;
        o.spp = opt.throughput_spp;
        for (int r = 0; r < opt.math_repeats; ++r) {
            o.seed = std::uint32_t(r);
            t_det.push_back(det.render(o).kernel_seconds);
            t_builtin.push_back(builtin.render(o).kernel_seconds);
        }
        res.det_math_seconds = least(t_det);
        res.builtin_math_seconds = least(t_builtin);
        res.det_math_cost = res.det_math_seconds / res.builtin_math_seconds - 1.0;
    }

    // Step 3: the reference, seed 0x7A4DE4 (no convergence render uses it).
    say("convergence " + std::to_string(opt.size) + "x" + std::to_string(opt.size) + ": warm-up");
    Setup setup(ctx, lib, desc, opt.size);
    say("reference: " + std::to_string(opt.reference_spp) + " spp");
    RenderOptions ro;
    ro.spp = opt.reference_spp;
    ro.seed = 0x7A4DE4u;
    const RenderResult ref = setup.render(ro);
    res.reference_seconds = ref.seconds;
    res.nan_guards += ref.nan_guards;

    // Step 4: spp = 1, 2, 4, ..., max_spp; the repeats go in interleaved rounds so that machine
    // noise hits every spp alike. Seeds 1, 2, 3, ... in order.
    std::vector<int> spps;
    for (int s = 1; s <= max_spp; s *= 2)
        spps.push_back(s);
    std::vector<std::vector<double>> wall(spps.size()), kernel(spps.size()), mse(spps.size()),
        rel(spps.size());
    std::uint32_t seed = 1;
    for (int round = 0; round < opt.repeats; ++round) {
        say("convergence round " + std::to_string(round + 1) + "/" + std::to_string(opt.repeats));
        for (std::size_t i = 0; i < spps.size(); ++i) {
            RenderOptions o;
            o.spp = spps[i];
            o.seed = seed++;
            const RenderResult r = setup.render(o);
            res.nan_guards += r.nan_guards;
            double se = 0, re = 0;
            for (std::size_t k = 0; k < r.rgb.size(); ++k) {
                const double d = double(r.rgb[k]) - ref.rgb[k];
                se += d * d;
                re += d * d / (double(ref.rgb[k]) * ref.rgb[k] + k_rel_eps);
            }
            wall[i].push_back(r.seconds);
            kernel[i].push_back(r.kernel_seconds);
            mse[i].push_back(se / double(r.rgb.size()));
            rel[i].push_back(re / double(r.rgb.size()));
        }
    }
    std::vector<double> log_t, log_e, log_n;
    for (std::size_t i = 0; i < spps.size(); ++i) {
        RenderConvergence c;
        c.spp = spps[i];
        c.seconds = least(wall[i]);
        c.kernel_seconds = least(kernel[i]);
        double m = 0, q = 0;
        for (std::size_t k = 0; k < mse[i].size(); ++k) {
            m += mse[i][k];
            q += rel[i][k];
        }
        c.rmse = std::sqrt(m / double(mse[i].size()));
        c.rel_mse = q / double(rel[i].size());
        res.convergence.push_back(c);
        log_t.push_back(std::log(c.seconds));
        log_e.push_back(std::log(c.rmse));
        log_n.push_back(std::log(double(c.spp)));
    }
    res.slope = fit_slope(log_t, log_e);
    res.slope_spp = fit_slope(log_n, log_e);
    res.total_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return res;
}

nlohmann::json RenderBenchResult::to_json() const {
    nlohmann::json j;
    j["scene"] = scene;
    j["device"] = device;
    j["throughput"] = nlohmann::json::array();
    for (const RenderThroughput& t : throughput)
        j["throughput"].push_back({{"width", t.width},
                                   {"height", t.height},
                                   {"spp", t.spp},
                                   {"seconds", t.seconds},
                                   {"kernel_seconds", t.kernel_seconds},
                                   {"samples_per_second", t.samples_per_second},
                                   {"kernel_samples_per_second", t.kernel_samples_per_second}});
    j["reference"] = {
        {"width", size}, {"height", size}, {"spp", reference_spp}, {"seconds", reference_seconds}};
    j["repeats"] = repeats;
    j["convergence"] = nlohmann::json::array();
    for (const RenderConvergence& c : convergence)
        j["convergence"].push_back({{"spp", c.spp},
                                    {"seconds", c.seconds},
                                    {"kernel_seconds", c.kernel_seconds},
                                    {"rmse", c.rmse},
                                    {"rel_mse", c.rel_mse}});
    j["slope"] = slope;
    j["slope_spp"] = slope_spp;
    j["det_math"] = {{"size", size},
                     {"det_kernel_seconds", det_math_seconds},
                     {"builtin_kernel_seconds", builtin_math_seconds},
                     {"cost", det_math_cost}};
    j["nan_guards"] = nan_guards;
    j["total_seconds"] = total_seconds;
    return j;
}

std::string RenderBenchResult::to_table() const {
    std::ostringstream out;
    char line[256];
    out << "scene: " << scene << "\ndevice: " << device << "\n\nthroughput (after one untimed "
        << "warm-up render per resolution)\n";
    std::snprintf(line, sizeof line, "%-10s %5s %10s %10s %13s %13s\n", "size", "spp", "wall s",
                  "kernel s", "wall Ms/s", "kernel Ms/s");
    out << line;
    for (const RenderThroughput& t : throughput) {
        const std::string size = std::to_string(t.width) + "x" + std::to_string(t.height);
        std::snprintf(line, sizeof line, "%-10s %5d %10.3f %10.3f %13.3f %13.3f\n", size.c_str(),
                      t.spp, t.seconds, t.kernel_seconds, t.samples_per_second * 1e-6,
                      t.kernel_samples_per_second * 1e-6);
        out << line;
    }
    std::snprintf(line, sizeof line,
                  "\ndeterministic math at %dx%d, %d spp, best kernel time: %.4f s; with the "
                  "built-ins %.4f s: cost %+.1f %%\n",
                  size, size, throughput.empty() ? 0 : throughput[0].spp, det_math_seconds,
                  builtin_math_seconds, 100.0 * det_math_cost);
    out << line;
    out << "\nconvergence at " << size << "x" << size << " against a " << reference_spp
        << " spp reference (" << reference_seconds << " s); best time and mean error of " << repeats
        << " independent seeds\n";
    std::snprintf(line, sizeof line, "%6s %10s %10s %12s %12s\n", "spp", "wall s", "kernel s",
                  "rmse", "rel mse");
    out << line;
    for (const RenderConvergence& c : convergence) {
        std::snprintf(line, sizeof line, "%6d %10.4f %10.4f %12.5g %12.5g\n", c.spp, c.seconds,
                      c.kernel_seconds, c.rmse, c.rel_mse);
        out << line;
    }
    if (std::isnan(slope) || std::isnan(slope_spp))
        std::snprintf(line, sizeof line,
                      "\nlog-log slope of rmse: n/a (one convergence point; --max-spp 2 or more "
                      "gives a line)\n");
    else
        std::snprintf(line, sizeof line,
                      "\nlog-log slope of rmse: %.3f against wall seconds, %.3f against spp "
                      "(expected -0.5)\n",
                      slope, slope_spp);
    out << line;
    if (nan_guards) out << nan_guards << " non-finite samples dropped\n";
    std::snprintf(line, sizeof line, "total %.1f s\n", total_seconds);
    out << line;
    return out.str();
}

std::string RenderBenchResult::convergence_csv() const {
    std::ostringstream out;
    char line[256];
    out << "spp,seconds,kernel_seconds,rmse,rel_mse\n";
    for (const RenderConvergence& c : convergence) {
        std::snprintf(line, sizeof line, "%d,%.6g,%.6g,%.6g,%.6g\n", c.spp, c.seconds,
                      c.kernel_seconds, c.rmse, c.rel_mse);
        out << line;
    }
    return out.str();
}

} // namespace tandem
