// Control-variate benchmarks.
#include "bench/cv_bench.h"

#include <algorithm>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "core/inverse/control_variate.h"
#include "core/inverse/gradient_step.h"
#include "runtime/error.h"

namespace tandem {

namespace {

/// The scene at a square resolution.
RenderScene scene_at(const std::string& path, int size) {
    SceneDesc desc = load_scene(path);
    desc.camera.width = desc.camera.height = size;
    return build_render_scene(desc);
}

} // namespace

CvBenchResult run_cv_bench(const CvBenchOptions& o) {
    Context ctx = Context::create(o.device);
    ctx.set_stage_timing(true);
    const KernelLibrary& lib = KernelLibrary::from_environment();
    CvBenchResult r;
    r.scene = o.scene;
    r.device = ctx.device().name;
    r.cost_size = o.cost_size;
    r.steady_size = o.steady_size;
    r.steady_runs = o.steady_runs;

    // 1. Cost: theta_{n-1} = the scene, theta_n = the changing parameters moved by a step, as in
    // an optimization (textures and albedos differ between the states in every element).
    {
        const RenderScene scene = scene_at(o.scene, o.cost_size);
        DeviceScene device(ctx, lib, scene);
        std::vector<float> now = scene.params.values();
        for (const std::string& name : o.changing) {
            const Parameter& p = scene.params.find(name);
            for (std::size_t i = p.offset; i < p.offset + p.size; ++i)
                now[i] = std::min(p.upper, now[i] * 0.9f + 0.05f);
        }
        Buffer<float> params(ctx, "params", now),
            params_old(ctx, "params (old)", scene.params.values());
        const std::size_t n = 3 * std::size_t(o.cost_size) * o.cost_size;
        Buffer<float> a(ctx, "image", n), b(ctx, "image (old)", n);
        // Device seconds of the render passes enqueued by `f`.
        auto render_seconds = [&](auto&& f) {
            ctx.stage_times();
            f();
            return stage_seconds(ctx.stage_times(), "render");
        };
        // warm-up: builds and caches
        render(device, params, 1, 1, a);
        render_two_state(device, params, params_old, 1, 1, a, b);
        r.primal_seconds = r.fused_seconds = r.pss_seconds = 1e30;
        for (int k = 0; k < o.cost_repeats; ++k) { // interleaved, so machine noise hits all alike
            const auto seed = static_cast<std::uint32_t>(100 + k);
            const double primal = render_seconds([&] { render(device, params, seed, 1, a); });
            const double fused = render_seconds(
                [&] { render_two_state(device, params, params_old, seed, 1, a, b); });
            const double pss = render_seconds([&] {
                render(device, params, seed, 1, a);
                render(device, params_old, seed, 1, b);
            });
            r.primal_seconds = std::min(r.primal_seconds, primal);
            r.fused_seconds = std::min(r.fused_seconds, fused);
            r.pss_seconds = std::min(r.pss_seconds, pss);
            if (o.progress) std::cerr << "cost round " << k + 1 << "/" << o.cost_repeats << "\n";
        }
        r.fused_cost_ratio = r.fused_seconds / r.primal_seconds;
        r.pss_cost_ratio = r.pss_seconds / r.primal_seconds;
    }

    // 2. Steady state: an unchanging scene, 1 spp per iteration, `steady_runs` independent runs.
    // Var[C_n] and Var[F] (one iteration's image) are measured across runs, per element, and
    // summed; their ratio is the effective sample count of the CV image.
    {
        const RenderScene scene = scene_at(o.scene, o.steady_size);
        ctx.set_stage_timing(false);
        DeviceScene device(ctx, lib, scene);
        ParamState state(ctx, scene.params);
        const std::size_t n = 3 * std::size_t(o.steady_size) * o.steady_size;
        const int last = *std::max_element(o.steady_iterations.begin(), o.steady_iterations.end());
        std::vector<std::vector<double>> sum_c(o.steady_iterations.size(),
                                               std::vector<double>(n, 0.0)),
            sum_c2 = sum_c;
        std::vector<double> sum_f(n, 0.0), sum_f2(n, 0.0), alpha(o.steady_iterations.size(), 0.0);
        ImageLoss loss(ctx, lib);
        Buffer<float> ref(ctx, "ref", 1), delta(ctx, "delta", n), image(ctx, "image", n),
            image_old(ctx, "image (old)", n);
        Buffer<gpu::CvState>& cv_state =
            state.add_buffer(GradientStep::k_cv_state, n, gpu::cv_state_zero());
        Buffer<float>& params = state.theta();
        for (int run = 0; run < o.steady_runs; ++run) {
            cv_state.fill(gpu::cv_state_zero());
            for (int it = 0; it < last; ++it) {
                render_two_state(device, params, params, primal_seed(0xC0FFEEu + run, it), 1, image,
                                 image_old);
                loss.evaluate_cv(LOSS_MEAN, image, image_old, cv_state,
                                 make_cv_config(unsigned(it)), ref, delta);
                if (it == 0) {
                    const std::vector<float> f = image.download();
                    for (std::size_t i = 0; i < n; ++i)
                        sum_f[i] += f[i], sum_f2[i] += double(f[i]) * f[i];
                }
                for (std::size_t k = 0; k < o.steady_iterations.size(); ++k)
                    if (it + 1 == o.steady_iterations[k]) {
                        const std::vector<gpu::CvState> st = cv_state.download();
                        double a = 0.0;
                        for (std::size_t i = 0; i < n; ++i) {
                            sum_c[k][i] += st[i].estimate;
                            sum_c2[k][i] += double(st[i].estimate) * st[i].estimate;
                            a += st[i].alpha;
                        }
                        alpha[k] += a / double(n) / o.steady_runs;
                    }
            }
            if (o.progress)
                std::cerr << "steady-state run " << run + 1 << "/" << o.steady_runs << "\n";
        }
        auto total_variance = [&](const std::vector<double>& s, const std::vector<double>& s2) {
            const double m = o.steady_runs;
            double v = 0.0;
            for (std::size_t i = 0; i < n; ++i)
                v += (s2[i] - s[i] * s[i] / m) / (m - 1.0);
            return v;
        };
        const double var_f = total_variance(sum_f, sum_f2);
        for (std::size_t k = 0; k < o.steady_iterations.size(); ++k) {
            r.iterations.push_back(o.steady_iterations[k]);
            r.effective_spp.push_back(var_f / total_variance(sum_c[k], sum_c2[k]));
            r.mean_alpha.push_back(alpha[k]);
        }
    }
    return r;
}

nlohmann::json CvBenchResult::to_json() const {
    nlohmann::json eff = nlohmann::json::object(), alpha = nlohmann::json::object();
    for (std::size_t k = 0; k < iterations.size(); ++k) {
        eff[std::to_string(iterations[k])] = effective_spp[k];
        alpha[std::to_string(iterations[k])] = mean_alpha[k];
    }
    return {{"scene", scene},
            {"device", device},
            {"cost_size", cost_size},
            {"primal_seconds", primal_seconds},
            {"fused_seconds", fused_seconds},
            {"pss_seconds", pss_seconds},
            {"fused_cost_ratio", fused_cost_ratio},
            {"pss_cost_ratio", pss_cost_ratio},
            {"steady_size", steady_size},
            {"steady_runs", steady_runs},
            {"effective_spp", eff},
            {"mean_alpha", alpha}};
}

std::string CvBenchResult::to_table() const {
    std::ostringstream s;
    s << "scene " << scene << ", device " << device << "\n" << std::fixed << std::setprecision(3);
    s << "cost at " << cost_size << "x" << cost_size << ", 1 spp (best device time): primal "
      << primal_seconds << " s, fused two-state " << fused_seconds << " s, CV-PSS " << pss_seconds
      << " s\n";
    s << "fused_cost_ratio " << std::setprecision(2) << fused_cost_ratio << ", pss_cost_ratio "
      << pss_cost_ratio << "\n";
    s << "steady state at " << steady_size << "x" << steady_size << ", 1 spp, " << steady_runs
      << " runs:\n";
    for (std::size_t k = 0; k < iterations.size(); ++k)
        s << "  iteration " << iterations[k] << ": effective_spp " << std::setprecision(1)
          << effective_spp[k] << ", mean alpha " << std::setprecision(3) << mean_alpha[k] << "\n";
    return s.str();
}

} // namespace tandem
