// `tandem optimize`: the optimization loop. run_optimization reads as the algorithm; the Run
// below holds what it sets up, and the steps of one iteration.
#include "core/inverse/optimize.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>

#include "core/inverse/checkpoint.h"
#include "core/inverse/gradient_step.h"
#include "core/inverse/grid_schedule.h"
#include "core/inverse/large_step_params.h"
#include "core/inverse/metrics.h"
#include "core/inverse/optimize_outputs.h"
#include "core/inverse/optimizer.h"
#include "core/inverse/session.h"
#include "core/inverse/streams.h"
#include "core/inverse/view_schedule.h"
#include "core/io/atomic_file.h"
#include "core/io/folder_lock.h"
#include "core/io/image_io.h"
#include "runtime/fault.h"

namespace tandem {

namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

/// The scene of `config`, loaded and checked against it (no device work): a config it stops
/// leaves no output folder.
RenderScene checked_scene(const OptimizeConfig& c) {
    const SceneDesc desc = load_scene(c.scene, c.defines);
    RenderScene scene = build_render_scene(desc);
    start_values(c, scene.params);
    return scene;
}

/// The output folder: created, and locked for this run alone (a second writer stops here, having
/// touched nothing).
struct OutputFolder {
    explicit OutputFolder(const std::string& dir)
        : path(created(dir)), lock(dir, "tandem optimize") {}
    static fs::path created(const std::string& dir) {
        std::error_code ec;
        fs::create_directories(dir, ec);
        if (ec || !fs::is_directory(dir))
            throw Error(dir + ": cannot create the output folder: " +
                        (ec ? ec.message() : std::string("Not a directory")));
        return fs::path(dir);
    }
    fs::path path;
    FolderLock lock; ///< held until the run ends, however it ends
};

OptimizerConfig optimizer_config(const OptimizeConfig& c) {
    return {c.optimizer == "adam" ? OptimizerConfig::Method::adam : OptimizerConfig::Method::sgd,
            c.beta1, c.beta2, c.epsilon};
}

/// One run: the session, the target, the gradient step, the optimizer and the outputs.
class Run {
public:
    Run(Context& ctx, const KernelLibrary& lib, const OptimizeConfig& c, const OptimizeOptions& o)
        : m_c(c), m_o(o), m_ranks(o.ranks ? *o.ranks : m_one_process),
          m_files_read(input_files(c)), m_scene_checked(checked_scene(c)),
          m_folder(m_ranks.root() ? std::make_unique<OutputFolder>(o.out_dir) : nullptr),
          m_out(o.out_dir), m_checkpoints(o.out_dir),
          m_session(ctx, lib, std::move(m_scene_checked), session_options(c)),
          m_start(start_values(c, m_session.scene().params)), m_state(m_session.state()) {
        const std::vector<const Parameter*>& optimized = m_start.optimized;
        const std::vector<unsigned> sensors = view_sensors(m_session, c);
        std::vector<ViewTarget> targets =
            load_targets(m_session, c, sensors, optimized, &m_reference_values);
        for (const ViewTarget& t : targets) {
            m_targets.push_back(t.reference);
            m_masks.push_back(t.mask);
        }
        const auto views = static_cast<unsigned>(sensors.size());
        if (c.batch > int(views))
            throw Error(c.path + ": 'batch' is " + std::to_string(c.batch) + ", more than the " +
                        std::to_string(views) + " view" + (views == 1 ? "" : "s"));
        const unsigned batch = c.batch == 0 ? views : unsigned(c.batch);
        if (m_ranks.size() > batch) // some rank would never have a view of the batch
            throw Error(c.path + ": " + std::to_string(m_ranks.size()) + " ranks for a batch of " +
                        std::to_string(batch) + " view" + (batch == 1 ? "" : "s") +
                        ": run at most " + std::to_string(batch) + " (mpirun -np)");
        m_schedule = std::make_unique<ViewSchedule>(views, batch, c.seed);

        m_summary.cv_variance = c.cv_variance;
        const CvMode plan = plan_cv(cv_mode(c.cv), optimized, &m_summary.cv_plan);
        // What the run will do, said once the setup has been checked (an error after the notes
        // would make them read as part of it).
        std::string notes = "tandem optimize: " + m_summary.cv_plan + "\n";
        m_step = std::make_unique<GradientStep>(m_session.device_scene(), lib, loss_kind(c.loss),
                                                std::move(targets), plan,
                                                cv_variance(c.cv_variance), batch);
        m_step->set_ranks(m_ranks);
        m_step->set_boundary_samples(c.boundary);
        try {
            if (c.restir) m_step->enable_restir(*c.restir, c.spp_grad, c.spp);
            if (c.boundary_reuse) m_step->enable_boundary_reuse(*c.boundary_reuse);
        } catch (const Error& e) {
            throw Error(c.path + ": " + e.what());
        }
        notes += reuse_notes(c);
        m_optimizer = std::make_unique<Optimizer>(m_state, lib, optimizer_config(c));
        m_grids = std::make_unique<GridSchedule>(m_state, lib, c, m_session.scene().params,
                                                 optimizer_config(c));
        m_grids->start(m_start.values); // (a resume replaces the coarse values)
        m_large_steps = std::make_unique<LargeStepParams>(m_state, lib, c, m_session.scene(),
                                                          optimizer_config(c));
        m_large_steps->start(m_start.values); // (a resume replaces u)
        m_step->attach(m_state);
        m_state.differentiate_only(optimized); // the gradients worth computing
        // the first change in the folder comes after it: a refused resume touches nothing
        resume();
        m_state.learning_rates().upload(m_large_steps->rates(m_grids->rates(m_start.lr)));
        notes += m_grids->plan() + m_large_steps->plan();
        notes += views_note();
        if (m_ranks.size() > 1) notes += ranks_note();
        for (const Parameter* p : optimized)
            m_optimized_now.resize(m_optimized_now.size() + p->size);
        notes += shape_gradient_gaps(m_session.scene(), optimized); // a warning, or ""
        if (m_step->restir() || m_step->restir_primal())
            m_summary.restir = m_step->restir_primal()
                                   ? (m_step->restir() ? "primal+adjoint" : "primal")
                                   : "adjoint";
        if (!m_ranks.root()) return; // rank 0 writes the folder
        if (const int stale = remove_stale_temporaries(o.out_dir))
            std::cerr << "tandem optimize: removed " << stale
                      << " unfinished file(s) an interrupted run left in " << o.out_dir << "\n";
        for (unsigned v = 0; v < views; ++v) write(v, "target.exr", m_targets[v]);
        std::cerr << notes;
        // The rows so far (the checkpoint's on --resume), then one appended per iteration.
        m_metrics = std::make_unique<RecordFile>((m_out / "metrics.csv").string(),
                                                 metrics_csv(m_progress.rows));
    }

    int start() const { return m_progress.iterations_done; }
    int end() const { return m_o.until > 0 ? std::min(m_o.until, m_c.iterations) : m_c.iterations; }

    /// Compiles every kernel an iteration uses, then, on a fresh run with ReSTIR, the burn-in of
    /// the reservoirs at theta_0 (timed as part of the run).
    void warm_up() {
        m_step->warm_up(m_state); // kernel compilation is not part of any iteration's time
        m_optimizer->warm_up();
        m_session.device_scene().reset_guards();
        if (!(m_step->restir() || m_step->restir_primal()) || start() != 0) return;
        // its passes run on their own (stage "restir"), and are not an iteration's "other" time
        timed(false, [&] {
            for (unsigned v = 0; v < m_step->views(); ++v) {
                if (!m_ranks.owns(v)) continue; // its reservoirs live on its own process
                const std::uint32_t seed = view_seed(m_c.seed, m_step->sensor(v));
                if (m_step->restir(v)) m_step->restir(v)->burn_in(m_state, seed);
                if (m_step->restir_primal(v)) m_step->restir_primal(v)->burn_in(m_state, seed);
            }
        });
    }

    /// Iteration `it` (0-based): the primal image(s), the loss, the adjoint and the step, and the
    /// values the metrics read back. Timed.
    MetricsRow iterate(int it) {
        MetricsRow row;
        row.iteration = it + 1;
        row.inputs_changed = m_inputs_changed;
        const auto n = std::uint32_t(it);
        const std::uint32_t seed = m_c.seed;
        const bool cv = m_step->cv() != CvMode::none;
        // the views of this iteration, each with its own streams (view_seed)
        std::vector<ViewPass> batch;
        for (const ViewSchedule::Visit& v : m_schedule->at(n))
            batch.push_back(ViewPass::of(v.view, v.visit, m_step->sensor(v.view), seed, n));
        m_last_batch = batch;
        timed(true, [&] {
            m_step->evaluate(m_state, batch, m_c.spp, m_c.spp_grad);
            if (cv || m_step->restir() || m_step->restir_primal())
                m_state.remember_theta(); // theta_n: the next iteration's old state
            m_optimizer->step();
            m_grids->step(it); // the scheduled grids (the state's optimizer leaves them)
            m_large_steps->step(it); // the meshes and textures of Large Steps (likewise)
            // Read back without blocking and waited for once with the loss: the optimized
            // parameters (param_error, the finiteness check) and the control weights.
            std::size_t at = 0;
            for (const Parameter* p : m_start.optimized) {
                m_state.theta().enqueue_read(p->offset, p->size, m_optimized_now.data() + at);
                at += p->size;
            }
            if (cv)
                for (const ViewPass& p : batch)
                    if (m_ranks.owns(p.view)) m_step->control_variate(p.view)->enqueue_alpha_read();
            m_session.context().finish(); // the iteration's one wait
            row.loss = m_step->loss();
        });
        row.seconds = m_progress.seconds + m_optimize_seconds;
        if (m_ranks.root())
            std::cerr << m_grids->changes(it) << geometry_note(m_session.device_scene(), it);
        return row;
    }

    /// The measurements of iteration `it` (not timed): the parameter error, the mean control
    /// weight, and at a milestone the re-render that image_error measures and the CV's images.
    void measure(int it, MetricsRow& row, bool milestone) {
        const std::string non_finite = non_finite_note(m_start.optimized, m_optimized_now);
        if (!non_finite.empty()) throw Error(non_finite); // run_optimization names the iteration
        if (!m_reference_values.empty())
            row.param_error = rmse(m_optimized_now, m_reference_values);
        if (m_step->cv() != CvMode::none) { // the mean over the batch's views, in its order
            std::vector<double> alphas(m_last_batch.size(), 0.0);
            for (std::size_t b = 0; b < m_last_batch.size(); ++b)
                if (m_ranks.owns(m_last_batch[b].view))
                    alphas[b] = m_step->control_variate(m_last_batch[b].view)->alpha_mean();
            m_ranks.gather_values(alphas);
            double sum = 0.0;
            for (double a : alphas) sum += a;
            row.alpha_mean = sum / double(m_last_batch.size());
        }
        if (!milestone) return;
        // the views' state that other processes keep, for the checkpoint and the CV's images;
        // rank 0 renders the measurements and writes them
        gather_view_state();
        if (!m_ranks.root()) return;
        double error = 0.0; // the mean over the views
        for (unsigned v = 0; v < m_step->views(); ++v) {
            const unsigned k = m_step->sensor(v);
            Buffer<float>& image = eval_image(k);
            render(View(m_session.device_scene(), k), m_state.theta(),
                   view_seed(stream_seed(m_c.seed, 0, Stream::evaluation), k), m_c.image_error_spp,
                   image);
            const std::vector<float> img = image.download();
            error += image_rmse(img, m_targets[v], m_masks[v]);
            write(v, iteration_name("iter_", it + 1), img);
            if (ControlVariate* cv = m_step->control_variate(v)) {
                // the view's state after its last visit (the iteration's, when in its batch)
                write(v, iteration_name("alpha_", it + 1), cv->alpha());
                write(v, iteration_name("variance_", it + 1),
                      cv->variance(visits_after(v, unsigned(it))));
            }
        }
        row.image_error = error / double(m_step->views());
        write_meshes(m_out.string(), it + 1, m_start.optimized, m_session.scene(), m_state);
    }

    /// The row into metrics.csv, and at a milestone the checkpoint and the plot.
    void record(int it, const MetricsRow& row, bool milestone) {
        m_progress.rows.push_back(row);
        const std::uint64_t counted = milestone ? guards() : 0; // (collective)
        if (!m_ranks.root()) return;
        m_metrics->append(metrics_csv_row(row));
        if (!milestone) return;
        CheckpointProgress now{it + 1, row.seconds, m_progress.rows, counted};
        // a fresh run's first checkpoint drops the previous one of whatever run was here before
        const auto t0 = Clock::now();
        m_step->store(m_state); // what the step keeps outside the state between checkpoints
        m_checkpoints.save(m_inputs, m_state, now, m_keep_previous);
        m_summary.checkpoint_seconds += seconds_since(t0);
        ++m_summary.checkpoints;
        m_keep_previous = true;
        write_convergence_plot((m_out / "convergence.png").string(), m_progress.rows);
    }

    /// The final parameters and plot, and the summary of the run.
    OptimizeSummary finish() {
        const std::vector<MetricsRow>& rows = m_progress.rows;
        if (m_ranks.root()) {
            write_parameters(m_out.string(), m_start.optimized, m_state.theta().download());
            if (!rows.empty()) write_convergence_plot((m_out / "convergence.png").string(), rows);
        }
        OptimizeSummary& s = m_summary;
        s.iterations_done = std::max(end(), m_resumed_at);
        s.ranks = m_ranks.size();
        s.exchanges = m_ranks.costs();
        s.guards = guards();
        s.inputs_changed = m_inputs_changed;
        if (!rows.empty()) {
            s.final_loss = rows.back().loss;
            s.param_error = rows.back().param_error;
            s.alpha_mean = rows.back().alpha_mean;
            for (const MetricsRow& r : rows)
                if (r.image_error >= 0.0) s.image_error = r.image_error;
        }
        return s;
    }

private:
    static SessionOptions session_options(const OptimizeConfig& c) {
        // ReSTIR and the boundary term's reuse both need the kernels built with RESTIR=1
        return {SessionOptions::Kernels::gradient, c.restir || c.boundary_reuse, {}};
    }
    /// The guards of the run so far, every process's (collective).
    std::uint64_t guards() {
        return m_progress.guards + m_ranks.sum(m_session.device_scene().read_guards());
    }
    /// Rank 0's copy of the state of every view another process keeps (GradientStep::view_state)
    /// <- that process's: rank 0's state is then the one a single process holds. Collective.
    void gather_view_state() {
        if (m_ranks.size() == 1) return;
        for (unsigned v = 0; v < m_step->views(); ++v) {
            const unsigned owner = v % m_ranks.size();
            if (owner == 0) continue;
            for (const std::string& name : m_step->view_state(v)) {
                std::string bytes = m_ranks.rank() == owner || m_ranks.root()
                                        ? m_state.buffer_bytes(name)
                                        : std::string();
                m_ranks.to_root(owner, bytes);
                if (m_ranks.root()) m_state.set_buffer_bytes(name, bytes);
            }
        }
    }
    /// The processes and their devices, for the log.
    std::string ranks_note() const {
        return "tandem optimize: " + std::to_string(m_ranks.size()) +
               " ranks; view v renders on rank v mod " + std::to_string(m_ranks.size()) + ": " +
               m_ranks.describe() + "\n";
    }
    /// Writes view v's image `name`: into the folder itself for a scene with one sensor, else
    /// into views/K/ (K: the sensor's index).
    void write(unsigned v, const std::string& name, const std::vector<float>& image) {
        const unsigned k = m_step->sensor(v);
        fs::path dir = m_out;
        if (m_session.sensors() > 1) {
            dir = m_out / "views" / std::to_string(k);
            std::error_code ec;
            fs::create_directories(dir, ec);
            if (ec) throw Error(dir.string() + ": cannot create the folder: " + ec.message());
        }
        write_image((dir / name).string(), int(m_session.width(k)), int(m_session.height(k)),
                    image);
    }
    /// The scratch image of sensor k's re-renders (one per film size).
    Buffer<float>& eval_image(unsigned k) {
        const std::size_t n = m_session.image_size(k);
        auto it = m_eval_images.find(n);
        if (it == m_eval_images.end())
            it = m_eval_images.emplace(n, Buffer<float>(m_session.context(), "evaluation image", n))
                     .first;
        return it->second;
    }
    /// How often view v was visited in iterations 0..it: its control variate's next iteration.
    unsigned visits_after(unsigned v, unsigned it) { return m_schedule->visits(v, it + 1); }
    /// The views and what they hold, for the log.
    std::string views_note() {
        std::size_t bytes = 0;
        for (unsigned v = 0; v < m_step->views(); ++v) bytes += m_step->view_bytes(v);
        std::ostringstream note;
        note << std::fixed << std::setprecision(1) << "tandem optimize: " << m_step->views()
             << (m_step->views() == 1 ? " view" : " views") << ", " << m_step->batch()
             << " per iteration; per-view state " << double(bytes) / double(1 << 20)
             << " MiB on the device (its target"
             << (m_step->cv() != CvMode::none ? ", control variate" : "")
             << (m_step->restir() || m_step->restir_primal() ? ", reservoirs" : "")
             << (m_step->batch() < m_step->views() ? ", last parameters" : "")
             << "), allocated once: it grows with the views and their films' pixels\n";
        return note.str();
    }

    /// The state at theta_0, or the checkpoint's with --resume.
    void resume() {
        m_inputs = run_inputs(m_session.scene(), m_c);
        for (std::size_t i = 0; i < m_inputs.files.size(); ++i)
            if (i >= m_files_read.size() || m_files_read[i].digest != m_inputs.files[i].digest)
                throw Error(m_inputs.files[i].path +
                            ": changed while this run was reading it; start it again");
        Checkpoints::Resumed r;
        const bool resumed =
            m_o.resume && m_checkpoints.resume(m_inputs, m_c.path, m_o.force, m_state, r);
        if (m_o.resume && !resumed && m_ranks.root())
            std::cerr << "tandem optimize: no checkpoint in " << m_o.out_dir
                      << " yet: starting from iteration 0\n";
        if (resumed) {
            m_step->restored(m_state);
            m_progress = std::move(r.progress);
            m_keep_previous = true;
        } else {
            m_session.set_values(m_start.values); // iteration 0: the old state is the new one
            m_step->reset_view_thetas(m_state);   // and each view's last parameters too
        }
        m_resumed_at = m_progress.iterations_done;
        if (m_o.until > 0 && m_o.until < start()) // nothing to do, and nothing rewritten
            throw Error(r.file + ": the checkpoint is at iteration " + std::to_string(start()) +
                        ", past --until " + std::to_string(m_o.until));
        // Every rank must start from the same point of the same inputs, or their exchanges no
        // longer match (a node that sees another folder, a file changed between two reads).
        // Collective: once it returns, every rank has read the checkpoint, and rank 0 may set
        // a damaged one aside.
        if (!m_ranks.agree(run_fingerprint(m_inputs, start())))
            throw Error(m_o.out_dir + ": the ranks do not agree on where the run starts (this rank: "
                        "iteration " + std::to_string(start()) + ") or on its input files: "
                        "every rank must see the same output folder and the same files");
        if (m_ranks.root()) {
            m_checkpoints.set_aside(r); // a damaged newest one, now that the resume holds
            if (!r.notice.empty()) std::cerr << "tandem optimize: " << r.notice << "\n";
        }
        m_inputs_changed = !r.changed.empty() ||
                           (!m_progress.rows.empty() && m_progress.rows.back().inputs_changed);
        if (!r.changed.empty() && m_ranks.root())
            std::cerr << "tandem optimize: --force: " << r.changed << "; resumed from " << r.file
                      << " at iteration " << start() << " anyway: metrics.csv marks the rows from "
                      << start() + 1 << " on (inputs_changed)\n";
    }

    /// Runs `f` timed: its wall seconds count towards the run's, and with stage timing its
    /// device seconds per stage towards the summary's (and the rest of its wall time towards
    /// other_seconds where `other`).
    template <class F> void timed(bool other, F&& f) {
        Context& ctx = m_session.context();
        ctx.set_stage_timing(m_o.stage_timing); // the stages of f only, not the measurements
        m_ranks.set_timing(m_o.stage_timing);  // and its exchanges with the other processes
        const auto t0 = Clock::now();
        f();
        ctx.finish();
        m_ranks.set_timing(false);
        const double seconds = seconds_since(t0);
        m_optimize_seconds += seconds;
        if (m_o.stage_timing) {
            const StepTimes t = StepTimes::from(ctx.stage_times());
            m_summary.primal_seconds += t.primal;
            m_summary.adjoint_seconds += t.adjoint;
            m_summary.restir_seconds += t.restir;
            if (other) m_summary.other_seconds += seconds - t.primal - t.adjoint - t.restir;
            ctx.set_stage_timing(false);
        }
    }

    const OptimizeConfig& m_c;
    const OptimizeOptions& m_o;
    OneProcess m_one_process;
    Ranks& m_ranks;
    /// The input files' digests before the session and the target read them: a file that changes
    /// while they do is an error, not a checkpoint of content the run never saw.
    std::vector<RunInputs::File> m_files_read;
    RenderScene m_scene_checked; ///< moved into the session
    std::unique_ptr<OutputFolder> m_folder; ///< rank 0's
    fs::path m_out;
    Checkpoints m_checkpoints;
    Session m_session;
    StartValues m_start;
    ParamState& m_state;
    std::vector<std::vector<float>> m_targets; ///< each view's target image
    std::vector<std::vector<float>> m_masks;   ///< and its mask (empty: none)
    std::vector<float> m_reference_values;
    std::unique_ptr<ViewSchedule> m_schedule;
    std::vector<ViewPass> m_last_batch;
    std::unique_ptr<GradientStep> m_step;
    std::unique_ptr<Optimizer> m_optimizer;
    std::unique_ptr<GridSchedule> m_grids;
    std::unique_ptr<LargeStepParams> m_large_steps;
    RunInputs m_inputs;
    bool m_keep_previous = false;  ///< checkpoint.bin is this run's (or the one it resumed)
    bool m_inputs_changed = false; ///< resumed with --force over changed inputs, now or before
    CheckpointProgress m_progress;
    int m_resumed_at = 0;
    std::unique_ptr<RecordFile> m_metrics;
    std::vector<float> m_optimized_now; ///< read back every iteration
    std::map<std::size_t, Buffer<float>> m_eval_images; ///< by size
    double m_optimize_seconds = 0.0; ///< the iterations proper, without measurements and outputs
    OptimizeSummary m_summary;
    /// The device may still write into m_optimized_now and the control weights if an error
    /// leaves an iteration between a read and its wait: drain the queue before they go.
    FinishOnExit m_drain{m_session.context()};
};

} // namespace

OptimizeSummary run_optimization(Context& ctx, const KernelLibrary& lib, const OptimizeConfig& c,
                                 const OptimizeOptions& o) {
    const auto t_start = Clock::now();
    Run run(ctx, lib, c, o); // the scene, the target, the step, the optimizer, the state
    run.warm_up();
    const int end = run.end();
    for (int it = run.start(); it < end; ++it) {
        fault::kill_point("iteration"); // tests: a kill between checkpoints
        const bool milestone = (it + 1) % c.checkpoint_every == 0 || it + 1 == end;
        MetricsRow row;
        try { // what stops an iteration (a step that destroys a mesh, say) names it
            row = run.iterate(it);
            run.measure(it, row, milestone);
        } catch (const Error& e) {
            throw Error("iteration " + std::to_string(it + 1) + ": " + e.what());
        }
        run.record(it, row, milestone);
        if (o.progress) o.progress(it + 1, c.iterations, row.loss);
    }
    OptimizeSummary summary = run.finish();
    summary.seconds = seconds_since(t_start);
    return summary;
}

} // namespace tandem
