// Control-variate benchmarks.
#include "bench/cv_bench.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "core/inverse/control_variate.h"
#include "core/inverse/session.h"
#include "runtime/error.h"

namespace tandem {

namespace {

/// The scene at a square resolution.
RenderScene scene_at(const std::string& path,
                     const std::vector<std::pair<std::string, std::string>>& defines, int size) {
    SceneDesc desc = load_scene(path, defines);
    desc.camera().width = desc.camera().height = size;
    return build_render_scene(desc);
}

} // namespace

CvBenchResult run_cv_bench(const CvBenchOptions& o) {
    Context ctx = Context::create(o.device, o.tuning);
    ctx.set_stage_timing(true);
    const KernelLibrary& lib = KernelLibrary::from_tuning(o.tuning);
    CvBenchResult r;
    r.scene = o.scene;
    r.device = ctx.device().name;
    r.cost_size = o.cost_size;
    r.steady_size = o.steady_size;
    r.steady_runs = o.steady_runs;

    // 1. Cost: theta_{n-1} = the scene, theta_n = the changing parameters moved by a step, as in
    // an optimization (textures and albedos differ between the states in every element).
    {
        Session session(ctx, lib, scene_at(o.scene, o.defines, o.cost_size));
        const RenderScene& scene = session.scene();
        DeviceScene& device = session.device_scene();
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

    // 2. Steady state: an unchanging scene, 1 spp per iteration, `steady_runs` independent runs
    // per variance form, all forms on the same seeds. Var[C_n] is measured across runs and Var[F]
    // (one iteration's 1-spp image) over every iteration n >= 1 of every run (on a static scene
    // they are iid), per element, and summed; their ratio is the effective sample count of the
    // CV image. The per-element bias of C_n is measured against a reference render
    // of `reference_spp` (its own variance, Var[F] / reference_spp, is part of the standard
    // error).
    {
        ctx.set_stage_timing(false);
        Session session(ctx, lib, scene_at(o.scene, o.defines, o.steady_size));
        DeviceScene& device = session.device_scene();
        ParamState& state = session.state();
        const std::size_t n = 3 * std::size_t(o.steady_size) * o.steady_size;
        const std::size_t checks = o.steady_iterations.size();
        const int last = *std::max_element(o.steady_iterations.begin(), o.steady_iterations.end());
        const double runs = o.steady_runs;
        ImageLoss loss(ctx, lib);
        Buffer<float> ref(ctx, "ref", 1), delta(ctx, "delta", n), image(ctx, "image", n),
            image_old(ctx, "image (old)", n);
        Buffer<float>& params = state.theta();

        Buffer<float> reference_image(ctx, "reference", n);
        render(device, params, 0xBEEF5EEDu, o.reference_spp, reference_image);
        const std::vector<float> reference = reference_image.download();
        r.reference_spp = o.reference_spp;

        std::vector<double> sum_f(n, 0.0), sum_f2(n, 0.0);
        // the plain running mean of the same samples, exactly unbiased: the calibration of z
        std::vector<std::vector<double>> sum_m(checks, std::vector<double>(n, 0.0)), sum_m2 = sum_m;
        std::vector<double> run_sum(n);
        for (std::size_t f_index = 0; f_index < o.variances.size(); ++f_index) {
            const std::string& form = o.variances[f_index];
            const bool first = f_index == 0; // the first form also collects F and the plain mean
            CvSettings settings;
            settings.variance = cv_variance(form);
            ControlVariate cv(loss, n, settings);
            std::vector<std::vector<double>> sum_c(checks, std::vector<double>(n, 0.0)),
                sum_c2 = sum_c;
            std::vector<double> alpha(checks, 0.0);
            for (int run = 0; run < o.steady_runs; ++run) {
                cv.reset();
                std::fill(run_sum.begin(), run_sum.end(), 0.0);
                for (int it = 0; it < last; ++it) {
                    render_two_state(device, params, params, primal_seed(0xC0FFEEu + run, it), 1,
                                     image, image_old);
                    cv.evaluate(unsigned(it), LOSS_MEAN, image, image_old, ref, delta);
                    if (it > 0 && first) { // every 1-spp f: iid
                        const std::vector<float> f = image.download();
                        for (std::size_t i = 0; i < n; ++i) {
                            sum_f[i] += f[i], sum_f2[i] += double(f[i]) * f[i];
                            run_sum[i] += f[i];
                        }
                        for (std::size_t k = 0; k < checks; ++k)
                            if (it + 1 == o.steady_iterations[k])
                                for (std::size_t i = 0; i < n; ++i) {
                                    const double m = run_sum[i] / it;
                                    sum_m[k][i] += m, sum_m2[k][i] += m * m;
                                }
                    }
                    for (std::size_t k = 0; k < checks; ++k)
                        if (it + 1 == o.steady_iterations[k]) {
                            const std::vector<gpu::CvState> st = cv.statistics().download();
                            double a = 0.0;
                            for (std::size_t i = 0; i < n; ++i) {
                                sum_c[k][i] += st[i].estimate;
                                sum_c2[k][i] += double(st[i].estimate) * st[i].estimate;
                                a += st[i].alpha;
                            }
                            alpha[k] += a / double(n) / runs;
                        }
                }
                if (o.progress)
                    std::cerr << form << " steady-state run " << run + 1 << "/" << o.steady_runs
                              << "\n";
            }
            auto variance_at = [&](const std::vector<double>& s, const std::vector<double>& s2,
                                   std::size_t i, double count) {
                return std::max(0.0, (s2[i] - s[i] * s[i] / count) / (count - 1.0));
            };
            const double f_count = runs * (last - 1);
            // effective spp and bias of the estimates whose sums over runs are (s, s2)
            auto measure = [&](const std::vector<double>& s, const std::vector<double>& s2,
                               double* effective_spp) {
                double var_f = 0.0, var_c = 0.0, abs_z = 0.0;
                std::size_t counted = 0, beyond = 0;
                for (std::size_t i = 0; i < n; ++i) {
                    const double vf = variance_at(sum_f, sum_f2, i, f_count);
                    const double vc = variance_at(s, s2, i, runs);
                    var_f += vf, var_c += vc;
                    const double se = std::sqrt(vc / runs + vf / o.reference_spp);
                    if (!(se > 0.0)) continue; // a constant element: no spread to measure against
                    const double z = (s[i] / runs - reference[i]) / se;
                    abs_z += std::fabs(z);
                    beyond += std::fabs(z) > 3.0;
                    ++counted;
                }
                *effective_spp = var_f / var_c;
                return CvBenchResult::Bias{counted ? abs_z / double(counted) : 0.0,
                                           counted ? double(beyond) / double(counted) : 0.0};
            };
            CvBenchResult::Form out;
            out.variance = form;
            for (std::size_t k = 0; k < checks; ++k) {
                double eff = 0.0;
                out.bias.push_back(measure(sum_c[k], sum_c2[k], &eff));
                out.effective_spp.push_back(eff);
                out.mean_alpha.push_back(alpha[k]);
            }
            r.forms.push_back(out);
            if (first)
                for (std::size_t k = 0; k < checks; ++k) {
                    double eff = 0.0;
                    r.running_mean_bias.push_back(measure(sum_m[k], sum_m2[k], &eff));
                }
        }
        r.iterations = o.steady_iterations;
    }
    return r;
}

nlohmann::json CvBenchResult::to_json() const {
    nlohmann::json eff = nlohmann::json::object(), alpha = nlohmann::json::object(),
                   bias = nlohmann::json::object();
    for (const Form& f : forms) {
        for (std::size_t k = 0; k < iterations.size(); ++k) {
            const std::string it = std::to_string(iterations[k]);
            eff[f.variance][it] = f.effective_spp[k];
            alpha[f.variance][it] = f.mean_alpha[k];
            bias[f.variance][it] = {{"mean_abs", f.bias[k].mean_abs_z},
                                    {"beyond_3", f.bias[k].beyond_3}};
        }
    }
    for (std::size_t k = 0; k < running_mean_bias.size(); ++k)
        bias["running_mean"][std::to_string(iterations[k])] = {
            {"mean_abs", running_mean_bias[k].mean_abs_z},
            {"beyond_3", running_mean_bias[k].beyond_3}};
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
            {"reference_spp", reference_spp},
            {"effective_spp", eff},
            {"mean_alpha", alpha},
            {"bias_z", bias}};
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
      << " runs; bias against " << reference_spp
      << " spp in standard errors (normal errors: mean |z| 0.80, 0.3% beyond 3; the plain mean "
         "of the samples, exactly unbiased, calibrates this scene's heavy tails):\n";
    for (std::size_t k = 0; k < running_mean_bias.size(); ++k)
        s << "  plain mean iteration " << std::setw(3) << iterations[k] << ": bias mean |z| "
          << std::setprecision(2) << running_mean_bias[k].mean_abs_z
          << ", beyond 3: " << std::setprecision(1) << 100.0 * running_mean_bias[k].beyond_3
          << "%\n";
    for (const Form& f : forms)
        for (std::size_t k = 0; k < iterations.size(); ++k)
            s << "  " << std::setw(10) << std::left << f.variance << std::right << " iteration "
              << std::setw(3) << iterations[k] << ": effective_spp " << std::setprecision(1)
              << std::setw(6) << f.effective_spp[k] << " (ideal " << iterations[k] - 1
              << "), mean alpha " << std::setprecision(3) << f.mean_alpha[k] << ", bias mean |z| "
              << std::setprecision(2) << f.bias[k].mean_abs_z
              << ", beyond 3: " << std::setprecision(1) << 100.0 * f.bias[k].beyond_3 << "%\n";
    return s.str();
}

} // namespace tandem
