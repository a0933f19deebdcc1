// `tandem optimize`: the optimization loop and its outputs.
#include "core/inverse/optimize.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "core/inverse/checkpoint.h"
#include "core/inverse/gradient_step.h"
#include "core/inverse/optimizer.h"
#include "core/io/atomic_file.h"
#include "core/io/image_io.h"
#include "runtime/fault.h"

namespace tandem {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

double rmse(const std::vector<float>& a, const std::vector<float>& b) {
    double s = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i)
        s += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
    return a.empty() ? 0.0 : std::sqrt(s / double(a.size()));
}

/// A file name for a parameter: its name with anything but [A-Za-z0-9._-] replaced by '_'.
std::string file_name(const std::string& name) {
    std::string out = name;
    for (char& ch : out)
        if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '.' && ch != '-' && ch != '_')
            ch = '_';
    return out;
}

std::string iteration_name(const char* prefix, int it) {
    std::ostringstream s;
    s << prefix << std::setw(4) << std::setfill('0') << it << ".exr";
    return s.str();
}

/// The target image, and the reference values of the optimized parameters when it is rendered
/// from a scene (empty otherwise).
std::vector<float> load_target(Context& ctx, const KernelLibrary& lib, const OptimizeConfig& c,
                               const RenderScene& scene,
                               const std::vector<const Parameter*>& optimized,
                               std::vector<float>* reference_values) {
    if (!c.target_image.empty())
        return read_film_image(c.target_image, "target", scene.camera.width, scene.camera.height);
    const SceneDesc tdesc = load_scene(c.target_scene, c.target_defines);
    const RenderScene tscene = build_render_scene(tdesc);
    if (tscene.camera.width != scene.camera.width || tscene.camera.height != scene.camera.height)
        throw Error(c.target_scene + ": the target scene's film differs from the scene's");
    DeviceScene target(ctx, lib, tscene);
    RenderOptions ro;
    ro.spp = c.target_spp;
    ro.seed = primal_seed(c.seed ^ 0x5bd1e995u, 0xFFFFFFFFu); // a stream no iteration uses
    const std::vector<float> image =
        render_image(target, parameter_buffer(ctx, tscene.params), ro).rgb;
    for (const Parameter* p : optimized) {
        const Parameter& q = tscene.params.find(p->name);
        if (q.size != p->size)
            throw Error(c.target_scene + ": parameter " + p->name + " has " +
                        std::to_string(q.size) + " values, the scene's has " +
                        std::to_string(p->size));
        reference_values->insert(reference_values->end(), tscene.params.values().begin() + q.offset,
                                 tscene.params.values().begin() + q.offset + q.size);
    }
    return image;
}

/// The start values and learning rates of `config` over the registry's layout; the optimized
/// parameters in `optimized`.
void start_values(const OptimizeConfig& c, const ParamRegistry& reg, std::vector<float>* values,
                  std::vector<float>* lr, std::vector<const Parameter*>* optimized) {
    *values = reg.values();
    lr->assign(reg.size(), 0.0f);
    for (const OptimizedParam& p : c.params) {
        const Parameter& q = [&]() -> const Parameter& {
            try {
                return reg.find(p.name);
            } catch (const Error& e) {
                throw Error(c.path + ": params: " + e.what());
            }
        }();
        optimized->push_back(&q);
        std::fill_n(lr->begin() + q.offset, q.size, p.lr);
        if (p.init.size() == 1) std::fill_n(values->begin() + q.offset, q.size, p.init[0]);
        if (p.init.size() == 3) {
            if (q.kind == Parameter::Kind::scalar)
                throw Error(c.path + ": params." + p.name + ": a scalar takes one 'init' value");
            for (std::size_t i = 0; i < q.size; ++i)
                (*values)[q.offset + i] = p.init[i % 3];
        }
        for (std::size_t i = q.offset; i < q.offset + q.size; ++i)
            if (!((*values)[i] >= q.lower && (*values)[i] <= q.upper)) {
                std::ostringstream m;
                m << c.path << ": params." << p.name << ": "
                  << (p.init.empty() ? "the scene's value " : "'init' ") << (*values)[i]
                  << " is outside the range it is optimized in, [" << q.lower << ", " << q.upper
                  << "]" << (p.init.empty() ? ": give an 'init' inside it" : "");
                throw Error(m.str());
            }
    }
    if (values->empty()) values->resize(1), lr->resize(1); // the state's buffers hold at least one
}

/// Final parameters: values in params.json, textures as images.
void write_parameters(const fs::path& out, const std::vector<const Parameter*>& optimized,
                      const std::vector<float>& values) {
    json pj = json::object();
    for (const Parameter* p : optimized) {
        if (p->kind == Parameter::Kind::texture) {
            const std::vector<float> texels(values.begin() + p->offset,
                                            values.begin() + p->offset + p->size);
            const std::string base = file_name(p->name);
            write_image((out / (base + ".exr")).string(), p->width, p->height, texels);
            write_image((out / (base + ".png")).string(), p->width, p->height, texels);
            pj[p->name] = {{"texture", base + ".exr"}, {"width", p->width}, {"height", p->height}};
        } else {
            pj[p->name] = std::vector<float>(values.begin() + p->offset,
                                             values.begin() + p->offset + p->size);
        }
    }
    write_file_atomic((out / "params.json").string(), pj.dump(2) + "\n");
}

} // namespace

OptimizeSummary run_optimization(Context& ctx, const KernelLibrary& lib, const OptimizeConfig& c,
                                 const OptimizeOptions& o) {
    const auto t_start = std::chrono::steady_clock::now();
    // The scene and the parameters first (no device work): a run they stop leaves no folder.
    const SceneDesc desc = load_scene(c.scene, c.defines);
    const RenderScene scene = build_render_scene(desc);
    const unsigned width = scene.camera.width, height = scene.camera.height;
    std::vector<float> values, lr;
    std::vector<const Parameter*> optimized;
    start_values(c, scene.params, &values, &lr, &optimized);

    std::error_code ec;
    fs::create_directories(o.out_dir, ec);
    if (ec || !fs::is_directory(o.out_dir))
        throw Error(o.out_dir + ": cannot create the output folder: " +
                    (ec ? ec.message() : std::string("Not a directory")));
    const fs::path out(o.out_dir);
    if (const int stale = remove_stale_temporaries(o.out_dir))
        std::cerr << "tandem optimize: removed " << stale
                  << " unfinished file(s) an interrupted run left in " << o.out_dir << "\n";
    BuildFlags features = render_features(scene, ctx);
    if (c.restir) features = restir_features(features);
    DeviceScene device(ctx, lib, scene, features);
    std::vector<float> reference_values;
    const std::vector<float> target = load_target(ctx, lib, c, scene, optimized, &reference_values);
    write_image((out / "target.exr").string(), int(width), int(height), target);

    std::string plan_reason;
    const CvMode plan = plan_cv(cv_mode(c.cv), optimized, &plan_reason);
    // What the run will do, said once the setup has been checked (an error after the notes
    // would make them read as part of it).
    std::ostringstream notes;
    notes << "tandem optimize: " << plan_reason << "\n";
    GradientStep step(device, lib, loss_kind(c.loss), target, plan, cv_variance(c.cv_variance));
    if (c.restir) {
        try {
            step.enable_restir(*c.restir, c.spp_grad, c.spp);
        } catch (const Error& e) {
            throw Error(c.path + ": " + e.what());
        }
        const RestirConfig& r = *c.restir;
        const char* where = r.adjoint && r.primal ? "the adjoint's and the primal's first vertex "
                                                    "(independent chains)"
                            : r.primal            ? "the primal's first vertex"
                                                  : "the adjoint's first vertex";
        notes << "tandem optimize: ReSTIR reuses light samples at " << where << " (" << r.candidates
              << " candidates, temporal " << (r.temporal ? "on" : "off") << ", " << r.spatial
              << " spatial, visibility " << (r.visibility ? "on" : "off") << "); deeper vertices"
              << (r.primal ? (r.adjoint ? "" : " and the adjoint") : " and the primal image")
              << " sample lights as before\n";
    }
    OptimizerConfig oc;
    oc.method =
        c.optimizer == "adam" ? OptimizerConfig::Method::adam : OptimizerConfig::Method::sgd;
    oc.beta1 = c.beta1;
    oc.beta2 = c.beta2;
    oc.epsilon = c.epsilon;
    Optimizer optimizer(ctx, lib, oc);

    ParamState state(ctx, scene.params);
    step.attach(state);
    state.learning_rates().upload(lr);
    state.differentiate_only(optimized); // the gradients worth computing
    const std::uint64_t fingerprint = run_fingerprint(scene, c);
    const std::string checkpoint_path = (out / "checkpoint.bin").string();
    CheckpointProgress progress;
    const bool resume = o.resume && fs::exists(checkpoint_path);
    if (o.resume && !resume)
        std::cerr << "tandem optimize: no checkpoint in " << o.out_dir
                  << " yet: starting from iteration 0\n";
    if (resume) {
        progress = load_checkpoint(checkpoint_path, fingerprint, state);
    } else {
        state.theta().upload(values);
        state.theta_prev().upload(values); // iteration 0: the old state is the new one
    }
    const int start = progress.iterations_done;
    if (o.until > 0 && o.until < start) // nothing to do, and nothing rewritten
        throw Error(checkpoint_path + ": the checkpoint is at iteration " + std::to_string(start) +
                    ", past --until " + std::to_string(o.until));
    std::cerr << notes.str();
    std::vector<MetricsRow>& rows = progress.rows;
    // The rows so far (the checkpoint's on --resume), then one appended per iteration.
    RecordFile metrics((out / "metrics.csv").string(), metrics_csv(rows));

    // What each iteration reads back, enqueued without blocking and waited for once with the
    // loss: the optimized parameters (for param_error and the finiteness check) and, with a
    // control variate, the control weights (alpha_mean).
    const std::size_t pixels = device.pixels();
    std::vector<float> optimized_now;
    for (const Parameter* p : optimized)
        optimized_now.resize(optimized_now.size() + p->size);
    Buffer<float> alpha(ctx, "control weights", plan == CvMode::none ? 1 : 3 * pixels);
    std::vector<float> alpha_now(alpha.size());
    Buffer<float> eval_image(ctx, "evaluation image", 3 * pixels);
    // The device may still write into optimized_now and alpha_now if an error leaves the loop
    // between a read and its wait: drain the queue before they go.
    const FinishOnExit drain(ctx);
    const std::uint32_t eval_seed = primal_seed(c.seed ^ 0x68e31da4u, 0xFFFFFFFFu);

    OptimizeSummary summary;
    summary.cv_plan = plan_reason;
    summary.cv_variance = c.cv_variance;
    if (step.restir() || step.restir_primal())
        summary.restir =
            step.restir_primal() ? (step.restir() ? "primal+adjoint" : "primal") : "adjoint";
    const int end = o.until > 0 ? std::min(o.until, c.iterations) : c.iterations;
    step.warm_up(state); // kernel compilation is not part of any iteration's time
    optimizer.warm_up();
    device.reset_guards();
    double optimize_seconds = 0.0; // the iterations proper, without measurements and outputs
    if ((step.restir() || step.restir_primal()) && start == 0) {
        // burn-in at theta_0, timed as part of the run (its passes run on their own: stage
        // "restir")
        ctx.set_stage_timing(o.stage_timing);
        const auto t0 = std::chrono::steady_clock::now();
        if (step.restir()) step.restir()->burn_in(state, c.seed);
        if (step.restir_primal()) step.restir_primal()->burn_in(state, c.seed);
        ctx.finish();
        if (o.stage_timing) {
            summary.restir_seconds += StepTimes::from(ctx.stage_times()).restir;
            ctx.set_stage_timing(false);
        }
        optimize_seconds +=
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }
    for (int it = start; it < end; ++it) {
        fault::kill_point("iteration");       // tests: a kill between checkpoints
        ctx.set_stage_timing(o.stage_timing); // the iteration's stages only, not the measurements
        const auto t0 = std::chrono::steady_clock::now();
        MetricsRow row;
        row.iteration = it + 1;
        const auto n = std::uint32_t(it);
        step.evaluate(
            state, unsigned(it), primal_seed(c.seed, n), c.spp, adjoint_seed(c.seed, n), c.spp_grad,
            GradientStep::RestirSeeds{restir_seed(c.seed, n), restir_primal_seed(c.seed, n)});
        if (plan != CvMode::none || step.restir() || step.restir_primal())
            state.remember_theta(); // theta_n: the next iteration's old state
        optimizer.step(state);
        std::size_t at = 0;
        for (const Parameter* p : optimized) {
            state.theta().enqueue_read(p->offset, p->size, optimized_now.data() + at);
            at += p->size;
        }
        if (plan != CvMode::none) {
            step.image_loss().cv_alpha(state.buffer<gpu::CvState>(GradientStep::k_cv_state), alpha);
            alpha.enqueue_read(0, alpha.size(), alpha_now.data());
        }
        ctx.finish(); // the iteration's one wait: the loss and the reads above arrive together
        row.loss = step.loss();
        const double iter_seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        optimize_seconds += iter_seconds;
        if (o.stage_timing) {
            const StepTimes t = StepTimes::from(ctx.stage_times());
            summary.primal_seconds += t.primal;
            summary.adjoint_seconds += t.adjoint;
            summary.restir_seconds += t.restir;
            summary.other_seconds += iter_seconds - t.primal - t.adjoint - t.restir;
            ctx.set_stage_timing(false);
        }

        // Measurements (not timed): parameter error, mean alpha, and every K iterations a
        // re-render.
        for (float v : optimized_now)
            if (!std::isfinite(v))
                throw Error("iteration " + std::to_string(it + 1) +
                            ": a parameter became non-finite");
        if (!reference_values.empty()) row.param_error = rmse(optimized_now, reference_values);
        if (plan != CvMode::none) {
            double sum = 0.0;
            for (float a : alpha_now)
                sum += a;
            row.alpha_mean = sum / double(alpha_now.size());
        }
        const bool milestone = (it + 1) % c.checkpoint_every == 0 || it + 1 == end;
        if (milestone) {
            render(device, state.theta(), eval_seed, c.image_error_spp, eval_image);
            const std::vector<float> img = eval_image.download();
            row.image_error = rmse(img, target);
            write_image((out / iteration_name("iter_", it + 1)).string(), int(width), int(height),
                        img);
            if (plan != CvMode::none) {
                const std::vector<gpu::CvState> cv =
                    state.buffer<gpu::CvState>(GradientStep::k_cv_state).download();
                std::vector<float> variance(cv.size());
                const gpu::CvConfig next = make_cv_config(unsigned(it + 1), step.cv_variance());
                for (std::size_t i = 0; i < cv.size(); ++i)
                    variance[i] = gpu::cv_estimate_variance(&cv[i], &next);
                write_image((out / iteration_name("alpha_", it + 1)).string(), int(width),
                            int(height), alpha_now);
                write_image((out / iteration_name("variance_", it + 1)).string(), int(width),
                            int(height), variance);
            }
        }
        row.seconds = progress.seconds + optimize_seconds;
        rows.push_back(row);
        metrics.append(metrics_csv_row(row));
        if (milestone) {
            CheckpointProgress now{it + 1, row.seconds, rows,
                                   progress.guards + device.read_guards()};
            save_checkpoint(checkpoint_path, fingerprint, state, now);
            write_convergence_plot((out / "convergence.png").string(), rows);
        }
        if (o.progress) o.progress(it + 1, c.iterations, row.loss);
    }
    write_parameters(out, optimized, state.theta().download());
    if (!rows.empty()) write_convergence_plot((out / "convergence.png").string(), rows);

    summary.iterations_done = end > start ? end : start;
    summary.guards = progress.guards + device.read_guards();
    if (!rows.empty()) {
        summary.final_loss = rows.back().loss;
        summary.param_error = rows.back().param_error;
        summary.alpha_mean = rows.back().alpha_mean;
        for (const MetricsRow& r : rows)
            if (r.image_error >= 0.0) summary.image_error = r.image_error;
    }
    summary.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
    return summary;
}

} // namespace tandem
