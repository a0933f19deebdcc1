// One gradient evaluation of inverse rendering, all on the device: primal image(s) -> image loss
// and its adjoint (through the recursive control variate when enabled) -> PRB gradient into the
// parameter state. The primal image that feeds the loss and the adjoint pass use independent
// seeds, so the product of their estimates is unbiased ("Recursive Control Variates for Inverse
// Rendering", Nicolet et al. 2023, Sec. 4; docs/method.md).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/inverse/control_variate.h"
#include "core/inverse/loss.h"
#include "core/inverse/param_state.h"
#include "core/inverse/ranks.h"
#include "core/inverse/restir.h"
#include "core/inverse/streams.h"
#include "core/render/boundary_reuse.h"
#include "core/render/passes.h"
#include "core/render/schedule.h"

namespace tandem {

/// Device seconds of the stages of an evaluation (with Context::set_stage_timing on).
struct StepTimes {
    double primal = 0.0, loss = 0.0, adjoint = 0.0, restir = 0.0;
    /// From Context::stage_times(): "render", "loss", "adjoint" and "restir" (the resampling
    /// passes of both chains).
    static StepTimes from(const std::vector<StageTime>& stages);
};

/// One view of an evaluation: a sensor of the scene and its target.
struct ViewTarget {
    unsigned sensor = 0;
    std::vector<float> reference; ///< 3 floats per pixel of the sensor's film; empty: LOSS_MEAN
    /// 1 float per pixel in [0, 1], the weight of the pixel's loss (a photograph's mask: 0 leaves
    /// it out); empty: every pixel counts fully
    std::vector<float> mask;
};

/// One view's part of an evaluation (GradientStep::evaluate).
struct ViewPass {
    unsigned view = 0;  ///< index into the step's views
    unsigned visit = 0; ///< evaluations of this view before this one: its control variate's n
    std::uint32_t seed_primal = 0, seed_adjoint = 0;
    /// The seeds of its resampling passes, with ReSTIR (restir_seed, restir_primal_seed).
    std::uint32_t seed_restir = 0, seed_restir_primal = 0;

    /// View `view` (sensor `sensor`) at its visit `visit`, in iteration `iteration` of a run
    /// seeded `seed`: each stream of the iteration, the sensor's own (view_seed).
    static ViewPass of(unsigned view, unsigned visit, unsigned sensor, std::uint32_t seed,
                       std::uint32_t iteration) {
        auto stream = [&](Stream s) { return view_seed(stream_seed(seed, iteration, s), sensor); };
        return {view, visit, stream(Stream::primal), stream(Stream::adjoint),
                stream(Stream::restir), stream(Stream::restir_primal)};
    }
};

class GradientStep {
public:
    /// The control variate's per-element statistics, a named buffer of the parameter state (of a
    /// scene with one sensor; a view's own otherwise: view_buffer).
    static constexpr const char* k_cv_state = ControlVariate::k_state;
    /// The parameters a view was last rendered with, per view, where a batch leaves views out
    /// (view_buffer): the old state of its next visit's control variate and reservoirs.
    static constexpr const char* k_view_theta = "view.theta";

    /// `reference`: the target image (3 floats per pixel of the scene's film); empty for
    /// LOSS_MEAN. With cv pss or ps, each evaluation also renders theta_prev and runs the
    /// recursive control variate. One view: sensor 0.
    GradientStep(DeviceScene& scene, const KernelLibrary& lib, unsigned loss,
                 const std::vector<float>& reference, CvMode cv = CvMode::none,
                 CvVariance cv_variance = CvVariance::consistent);
    /// Several views, each with its own target, control variate and reservoirs (per-view state in
    /// the parameter state), evaluated `batch` at a time (0: all of them every time). Throws Error
    /// for a sensor the scene lacks, a view listed twice or a target of another size.
    GradientStep(DeviceScene& scene, const KernelLibrary& lib, unsigned loss,
                 std::vector<ViewTarget> views, CvMode cv, CvVariance cv_variance,
                 unsigned batch = 0);

    /// Reuses light samples across evaluations (ReSTIR, core/inverse/restir.h): in the adjoint
    /// for `spp_grad` samples per pixel where config.adjoint, and in a chain of its own in the
    /// primal image for `spp` where config.primal (without a control variate and with spp >= 1
    /// only: throws Error otherwise); each view has its own chains. The scene must be built with
    /// restir_features(). Call before attach().
    void enable_restir(const RestirConfig& config, int spp_grad, int spp = 0);
    /// The boundary terms' sample budgets of shape gradients (core/render/passes.h). Where
    /// enable_boundary_reuse() made the step reservoirs of its own, they stay in b.reuse's place.
    void set_boundary_samples(BoundarySamples b) {
        m_boundary = b;
        if (m_boundary_reuse) m_boundary.reuse = m_boundary_reuse.get();
    }
    /// Reuses the secondary boundary term's light vertices across evaluations (core/render/
    /// boundary_reuse.h): one set of reservoirs, in world space, serves every view. The scene
    /// must be built with restir_features(); one process only (throws Error otherwise). Call
    /// before attach().
    void enable_boundary_reuse(const SecondaryReuseConfig& config);
    SecondaryReservoirs* boundary_reuse() { return m_boundary_reuse.get(); }
    /// Copies what the step keeps outside `state` between evaluations (the boundary term's
    /// reservoirs) into it: before a checkpoint is saved.
    void store(ParamState& state);
    /// Takes it back: after a checkpoint was restored into `state`.
    void restored(ParamState& state);
    /// The seeds of one iteration's resampling passes (restir_seed, restir_primal_seed).
    struct RestirSeeds {
        std::uint32_t adjoint = 0, primal = 0;
    };
    /// View `view`'s adjoint chain, or null.
    Restir* restir(unsigned view = 0) { return m_views.at(view).restir.get(); }
    /// View `view`'s primal chain, or null.
    Restir* restir_primal(unsigned view = 0) { return m_views.at(view).restir_primal.get(); }

    /// Registers what `state` must carry for this evaluation (each view's CV statistics,
    /// reservoirs, and last parameters where a batch leaves views out): call once before the
    /// first evaluate() on it, and before restoring a checkpoint into it. The control variates
    /// keep their statistics there from then on.
    void attach(ParamState& state);
    /// Each view's last parameters <- state.theta() (a fresh run's start values, once set).
    void reset_view_thetas(ParamState& state);
    /// Spreads the views over the processes of `ranks` (it must outlive the step): evaluate()
    /// then renders and back-propagates the views of a batch that this process owns
    /// (Ranks::owns), and exchanges what the step needs from the others' exactly, so that the
    /// gradient, the loss and the step are the bits of one process's. Default: one process.
    void set_ranks(Ranks& ranks) { m_ranks = &ranks; }
    Ranks& ranks() { return *m_ranks; }
    /// The names of the parameter state's buffers that view `view` alone updates (its control
    /// variate's statistics, its reservoirs), which live on the process that owns it.
    std::vector<std::string> view_state(unsigned view) const;

    /// Enqueues the evaluation of the views of `batch` at state.theta(), whose gradients add into
    /// state.gradient(): for each view, its primal image(s) (seed_primal, spp), its loss and
    /// delta; then one gradient scale for the batch (choose_gradient_scale), each view's PRB
    /// replay (seed_adjoint, spp_grad) into the one fixed-point accumulator, and one decode.
    /// With the control variate, a view's old state is the parameters it was last rendered
    /// with: theta_prev when every view is in every batch, else its own copy (k_view_theta);
    /// its statistics are updated at its visits only, and `visit` is their count. With ReSTIR,
    /// each adjoint path first refreshes its view's reservoir at its first hit from the view's
    /// previous ones, whose domain is that same old state, and reads it; the primal chain does
    /// the same with its own. The loss is the sum of the views' losses (read with loss()).
    void evaluate(ParamState& state, const std::vector<ViewPass>& batch, int spp, int spp_grad);
    /// One view (view 0) at iteration `iteration`, which is its visit.
    void evaluate(ParamState& state, unsigned iteration, std::uint32_t seed_primal, int spp,
                  std::uint32_t seed_adjoint, int spp_grad,
                  std::optional<RestirSeeds> restir = std::nullopt);
    /// The loss of the last evaluate() (of the control-variate estimates with a CV), summed over
    /// its views in the batch's order; waits (and, over several processes, is collective).
    float loss();

    /// Launches every kernel an evaluation uses once, on scratch data (PoCL compiles a kernel on
    /// its first launch), so that timed iterations measure rendering, not compilation. Leaves
    /// the state as it was.
    void warm_up(ParamState& state);

    CvMode cv() const { return m_cv; }
    CvVariance cv_variance() const { return m_cv_variance; }
    unsigned views() const { return static_cast<unsigned>(m_views.size()); }
    unsigned sensor(unsigned view) const { return m_views.at(view).sensor; }
    /// Views per evaluation the step was built for (all of them: views()).
    unsigned batch() const { return m_batch; }
    /// View `view`'s control variate (its alpha and variance images), or null without one.
    ControlVariate* control_variate(unsigned view = 0) { return m_views.at(view).control.get(); }
    DeviceScene& scene() { return m_scene; }
    /// <F_n>_n of the last view evaluated (the scratch of its film's size).
    Buffer<float>& image() { return *m_last_image; }
    Buffer<float>& image_old() { return *m_last_image_old; } ///< <F_{n-1}>_n (control variate)
    /// dloss/dimage of the view in slot `slot` of the last evaluation's batch (this process's).
    Buffer<float>& delta(unsigned slot = 0);
    /// Device bytes each view holds of its own: its target (and mask), its control variate's
    /// statistics and control weights, its reservoirs and its last parameters. The images of an
    /// evaluation and the deltas of a batch are scratch, per film size (and per slot of the batch),
    /// shared by the views.
    std::size_t view_bytes(unsigned view) const;

private:
    BoundarySamples m_boundary;
    std::unique_ptr<SecondaryReservoirs> m_boundary_reuse;
    struct ViewState {
        unsigned sensor = 0;
        Buffer<float> reference, mask;
        std::unique_ptr<ControlVariate> control;
        std::unique_ptr<Restir> restir, restir_primal;
    };
    struct Scratch {
        Buffer<float> image, image_old;
    };
    Scratch& scratch(std::size_t pixels);
    /// Slot `slot`'s delta of `floats` elements (a batch's deltas live until its adjoints ran).
    Buffer<float>& slot_delta(std::size_t slot, std::size_t floats);
    /// The parameters view `v` was last rendered with: theta_prev, or its own copy.
    Buffer<float>& old_theta(ParamState& state, unsigned v);
    std::string state_name(const char* name, unsigned v) const;

    DeviceScene& m_scene;
    OneProcess m_one_process;
    Ranks* m_ranks = &m_one_process;
    /// The last evaluation's batch size, and the slots of it this process evaluated (the order
    /// of its losses)
    std::size_t m_last_batch = 0;
    std::vector<std::size_t> m_own_slots;
    /// Wrapped sums this process decodes from words the first process decodes and counts too
    Buffer<unsigned> m_uncounted;
    unsigned m_kind;
    CvMode m_cv;
    CvVariance m_cv_variance;
    unsigned m_batch;
    ImageLoss m_loss;
    std::vector<ViewState> m_views;
    std::map<std::size_t, Scratch> m_scratch; ///< by pixel count
    std::vector<std::map<std::size_t, Buffer<float>>> m_deltas; ///< per slot, by size
    std::vector<Buffer<float>*> m_last_deltas; ///< the last batch's, by slot (null: not ours)
    Buffer<float>* m_last_image = nullptr;
    Buffer<float>* m_last_image_old = nullptr;
};

} // namespace tandem
