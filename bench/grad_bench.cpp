// Time per optimization iteration.
#include "bench/grad_bench.h"

#include <chrono>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "core/inverse/optimizer.h"
#include "core/inverse/session.h"
#include "runtime/error.h"

namespace tandem {

GradBenchResult run_grad_bench(const GradBenchOptions& o) {
    Context ctx = Context::create(o.device, o.tuning);
    const KernelLibrary& lib = KernelLibrary::from_tuning(o.tuning);
    GradBenchResult result;
    result.scene = o.scene;
    result.param = o.param;
    result.device = ctx.device().name;
    result.spp = o.spp;
    result.iterations = o.iterations;
    for (int size : o.sizes) {
        SceneDesc desc = load_scene(o.scene);
        desc.camera().width = desc.camera().height = size;
        Session session(ctx, lib, build_render_scene(desc));
        const RenderScene& scene = session.scene();
        const Parameter& p = scene.params.find(o.param);
        // The target: the scene itself at 4x the spp; the run starts from a flat 0.5.
        RenderOptions ro;
        ro.spp = 4 * o.spp;
        ro.seed = 12345;
        const std::vector<float> target = session.render_image(ro).rgb;
        std::vector<float> values = scene.params.values(), lr(values.size(), 0.0f);
        std::fill_n(values.begin() + p.offset, p.size, 0.5f);
        std::fill_n(lr.begin() + p.offset, p.size, 0.01f);
        ParamState& state = session.state();
        state.differentiate_only({&p});
        state.theta().upload(values);
        state.learning_rates().upload(lr);
        const std::unique_ptr<GradientStep> step = session.gradient_step(LOSS_L1, target);
        Optimizer adam(state, lib, OptimizerConfig{});
        GradBenchRow row;
        row.size = size;
        for (int it = -1; it < o.iterations; ++it) { // iteration -1: warm-up (kernel builds)
            ctx.set_stage_timing(true);
            ctx.stage_times(); // forget earlier stages
            const auto t0 = std::chrono::steady_clock::now();
            step->evaluate(state, unsigned(it + 1), primal_seed(1, it + 1), o.spp,
                           adjoint_seed(1, it + 1), o.spp);
            adam.step();
            step->loss(); // the iteration's one wait, as in tandem optimize
            const double wall =
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
            const StepTimes times = StepTimes::from(ctx.stage_times());
            if (it < 0) continue;
            row.iteration += wall / o.iterations;
            row.primal += times.primal / o.iterations;
            row.adjoint += times.adjoint / o.iterations;
        }
        row.other = row.iteration - row.primal - row.adjoint;
        if (o.progress)
            std::cerr << size << "x" << size << ": " << row.iteration << " s per iteration\n";
        result.rows.push_back(row);
    }
    return result;
}

nlohmann::json GradBenchResult::to_json() const {
    nlohmann::json rows_json = nlohmann::json::array();
    for (const GradBenchRow& r : rows)
        rows_json.push_back({{"size", r.size},
                             {"iteration_seconds", r.iteration},
                             {"primal_seconds", r.primal},
                             {"adjoint_seconds", r.adjoint},
                             {"other_seconds", r.other},
                             {"adjoint_over_primal", r.adjoint / r.primal}});
    return {{"scene", scene}, {"param", param},           {"device", device},
            {"spp", spp},     {"iterations", iterations}, {"rows", rows_json}};
}

std::string GradBenchResult::to_table() const {
    std::ostringstream s;
    s << "scene " << scene << ", parameter " << param << ", " << spp
      << " spp primal and adjoint, mean of " << iterations << " iterations, device " << device
      << "\n";
    s << "| size | iteration (s) | primal (s) | adjoint (s) | other (s) | adjoint / primal |\n"
      << "|---|---|---|---|---|---|\n"
      << std::fixed;
    for (const GradBenchRow& r : rows)
        s << "| " << r.size << "² | " << std::setprecision(3) << r.iteration << " | " << r.primal
          << " | " << r.adjoint << " | " << r.other << " | " << std::setprecision(2)
          << r.adjoint / r.primal << " |\n";
    return s.str();
}

} // namespace tandem
