// One step of inverse rendering.
#include "core/inverse/gradient_step.h"

#include "core/render/boundary.h"

#include <functional>

#include "core/inverse/control_variate.h"
#include "core/inverse/secondary_reuse_state.h"
#include "runtime/error.h"

namespace tandem {

StepTimes StepTimes::from(const std::vector<StageTime>& stages) {
    StepTimes t;
    t.primal = stage_seconds(stages, "render");
    t.loss = stage_seconds(stages, "loss");
    t.adjoint = stage_seconds(stages, "adjoint");
    t.restir = stage_seconds(stages, "restir");
    return t;
}

GradientStep::GradientStep(DeviceScene& scene, const KernelLibrary& lib, unsigned loss,
                           const std::vector<float>& reference, CvMode cv, CvVariance cv_variance)
    : GradientStep(scene, lib, loss, std::vector<ViewTarget>{ViewTarget{0, reference, {}}}, cv,
                   cv_variance) {}

GradientStep::GradientStep(DeviceScene& scene, const KernelLibrary& lib, unsigned loss,
                           std::vector<ViewTarget> views, CvMode cv, CvVariance cv_variance,
                           unsigned batch)
    : m_scene(scene), m_kind(loss), m_cv(cv), m_cv_variance(cv_variance),
      m_batch(batch == 0 ? static_cast<unsigned>(views.size()) : batch),
      m_loss(scene.context(), lib) {
    Context& ctx = scene.context();
    if (views.empty()) throw Error("a gradient step needs a view");
    if (m_batch > views.size())
        throw Error("a batch of " + std::to_string(m_batch) + " views out of " +
                    std::to_string(views.size()));
    for (ViewTarget& t : views) {
        const std::string sensor = "sensor " + std::to_string(t.sensor);
        const std::size_t n = 3 * tandem::View(scene, t.sensor).pixels();
        for (const ViewState& v : m_views)
            if (v.sensor == t.sensor) throw Error(sensor + " is listed twice among the views");
        if (loss != LOSS_MEAN && t.reference.size() != n)
            throw Error("the reference image of " + sensor + " has " +
                        std::to_string(t.reference.size() / 3) + " pixels, the sensor renders " +
                        std::to_string(n / 3));
        if (!t.mask.empty() && t.mask.size() != n / 3)
            throw Error("the mask of " + sensor + " has " + std::to_string(t.mask.size()) +
                        " pixels, the sensor renders " + std::to_string(n / 3));
        ViewState v;
        v.sensor = t.sensor;
        v.reference = Buffer<float>(ctx, "reference",
                                    t.reference.empty() ? std::vector<float>(1, 0.0f) : t.reference);
        if (!t.mask.empty()) v.mask = Buffer<float>(ctx, "mask", t.mask);
        if (cv != CvMode::none) {
            ControlVariate::Settings settings;
            settings.variance = cv_variance;
            v.control = std::make_unique<ControlVariate>(m_loss, n, settings);
        }
        scratch(n / 3);
        if (m_views.size() < m_batch) slot_delta(m_views.size(), n); // the batch's, allocated once
        m_views.push_back(std::move(v));
        t = ViewTarget{}; // the host copies go once uploaded
    }
    prepare_passes(scene, cv == CvMode::ps, true); // compile now, not inside a timed iteration
}

GradientStep::Scratch& GradientStep::scratch(std::size_t pixels) {
    auto it = m_scratch.find(pixels);
    if (it != m_scratch.end()) return it->second;
    Context& ctx = m_scene.context();
    Scratch s;
    s.image = Buffer<float>(ctx, "image", 3 * pixels);
    s.image_old = Buffer<float>(ctx, "image (previous state)", m_cv == CvMode::none ? 1 : 3 * pixels);
    Scratch& made = m_scratch.emplace(pixels, std::move(s)).first->second;
    if (!m_last_image) {
        m_last_image = &made.image;
        m_last_image_old = &made.image_old;
    }
    return made;
}

std::string GradientStep::state_name(const char* name, unsigned v) const {
    return view_buffer(name, m_views.at(v).sensor, m_scene.sensors());
}

Buffer<float>& GradientStep::slot_delta(std::size_t slot, std::size_t floats) {
    if (m_deltas.size() <= slot) m_deltas.resize(slot + 1);
    auto it = m_deltas[slot].find(floats);
    if (it == m_deltas[slot].end())
        it = m_deltas[slot].emplace(floats, Buffer<float>(m_scene.context(), "loss adjoint", floats))
                 .first;
    return it->second;
}

Buffer<float>& GradientStep::old_theta(ParamState& state, unsigned v) {
    if (m_batch == m_views.size()) return state.theta_prev();
    return state.buffer<float>(state_name(k_view_theta, v));
}

std::size_t GradientStep::view_bytes(unsigned view) const {
    const ViewState& v = m_views.at(view);
    std::size_t bytes = 0;
    if (m_kind != LOSS_MEAN) bytes += v.reference.size() * sizeof(float);
    bytes += v.mask.size() * sizeof(float);
    if (v.control) // its statistics, and its control weights for the metrics
        bytes += v.control->elements() * (sizeof(gpu::CvState) + sizeof(float));
    for (const Restir* r : {v.restir.get(), v.restir_primal.get()})
        if (r) bytes += 2 * r->slots() * sizeof(gpu::Reservoir); // previous and current
    if (m_batch < m_views.size()) bytes += m_scene.param_count() * sizeof(float);
    return bytes;
}

void GradientStep::enable_restir(const RestirConfig& config, int spp_grad, int spp) {
    if (config.primal && m_cv != CvMode::none)
        throw Error("restir: reuse in the primal needs no control variate (its two states share "
                    "their paths; docs/restir.md)");
    if (config.primal && spp < 1)
        throw Error("restir: reuse in the primal needs the primal's samples per pixel");
    for (ViewState& v : m_views) {
        const tandem::View view(m_scene, v.sensor);
        v.restir.reset();
        v.restir_primal.reset();
        if (config.adjoint) v.restir = std::make_unique<Restir>(view, config, spp_grad);
        if (config.primal)
            v.restir_primal = std::make_unique<Restir>(view, config, spp, RestirChain::primal);
    }
}

void GradientStep::enable_boundary_reuse(const SecondaryReuseConfig& config) {
    if (m_ranks->size() > 1)
        throw Error("the boundary term's reuse runs in one process (its reservoirs serve every "
                    "view); run without mpirun or without restir.boundary");
    m_boundary_reuse = std::make_unique<SecondaryReservoirs>(m_scene.context(), config);
    m_boundary.reuse = m_boundary_reuse.get();
}

void GradientStep::store(ParamState& state) {
    if (m_boundary_reuse) store_secondary_reuse(*m_boundary_reuse, state);
}

void GradientStep::restored(ParamState& state) {
    if (m_boundary_reuse) load_secondary_reuse(state, *m_boundary_reuse);
}

void GradientStep::attach(ParamState& state) {
    if (m_boundary_reuse) attach_secondary_reuse(state);
    for (unsigned i = 0; i < views(); ++i) {
        ViewState& v = m_views[i];
        if (v.control) v.control->attach(state, state_name(k_cv_state, i));
        if (v.restir) v.restir->attach(state);
        if (v.restir_primal) v.restir_primal->attach(state);
        const std::string theta = state_name(k_view_theta, i);
        if (m_batch < m_views.size() && !state.has_buffer(theta))
            state.add_buffer(theta, state.size(), 0.0f).copy_from(state.theta());
    }
}

void GradientStep::reset_view_thetas(ParamState& state) {
    if (m_batch < m_views.size())
        for (unsigned v = 0; v < views(); ++v) old_theta(state, v).copy_from(state.theta());
}

void GradientStep::evaluate(ParamState& state, unsigned iteration, std::uint32_t seed_primal,
                            int spp, std::uint32_t seed_adjoint, int spp_grad,
                            std::optional<RestirSeeds> restir) {
    if ((m_views[0].restir || m_views[0].restir_primal) && !restir)
        throw Error("restir: an evaluation with reservoirs needs the seeds of its passes");
    ViewPass pass;
    pass.visit = iteration;
    pass.seed_primal = seed_primal;
    pass.seed_adjoint = seed_adjoint;
    if (restir) {
        pass.seed_restir = restir->adjoint;
        pass.seed_restir_primal = restir->primal;
    }
    evaluate(state, {pass}, spp, spp_grad);
}

void GradientStep::evaluate(ParamState& state, const std::vector<ViewPass>& batch, int spp,
                            int spp_grad) {
    if (batch.empty() || batch.size() > m_batch)
        throw Error("an evaluation takes 1 to " + std::to_string(m_batch) + " views, not " +
                    std::to_string(batch.size()));
    for (std::size_t b = 0; b < batch.size(); ++b) {
        const ViewPass& p = batch[b];
        for (std::size_t c = 0; c < b; ++c)
            if (batch[c].view == p.view) // its statistics and reservoirs would advance twice
                throw Error("view " + std::to_string(p.view) + " is twice in one batch");
        const ViewState& v = m_views.at(p.view);
        if (v.restir && v.restir->spp() != spp_grad)
            throw Error("restir: the reservoirs are for " + std::to_string(v.restir->spp()) +
                        " adjoint samples per pixel, not " + std::to_string(spp_grad));
        if (v.restir_primal && v.restir_primal->spp() != spp)
            throw Error("restir: the primal's reservoirs are for " +
                        std::to_string(v.restir_primal->spp()) + " samples per pixel, not " +
                        std::to_string(spp));
    }
    const Buffer<float>& theta = state.theta();
    // shapes this gradient follows: the primal renders trace them where theta says (a resumed
    // run's first image too, before any adjoint has run)
    if (differentiates_geometry(m_scene.scene(), state.gradient())) m_scene.track_geometry();
    // the primal image(s), the loss and its delta of every view this process owns
    m_last_deltas.assign(batch.size(), nullptr);
    m_last_batch = batch.size();
    m_own_slots.clear();
    for (std::size_t b = 0; b < batch.size(); ++b) {
        const ViewPass& p = batch[b];
        if (!m_ranks->owns(p.view)) continue;
        ViewState& v = m_views.at(p.view);
        const tandem::View view(m_scene, v.sensor);
        Scratch& s = scratch(view.pixels());
        Buffer<float>& delta = slot_delta(b, 3 * view.pixels());
        m_last_deltas[b] = &delta;
        m_last_image = &s.image;
        m_last_image_old = &s.image_old;
        const Buffer<float>* mask = v.mask.size() ? &v.mask : nullptr;
        const bool add = !m_own_slots.empty(); // the batch's loss is the sum of its views'
        m_own_slots.push_back(b);
        switch (m_cv) {
        case CvMode::none:
            if (v.restir_primal) {
                render(view, theta, p.seed_primal, spp, s.image,
                       v.restir_primal->resampled_by_paths(state, p.seed_restir_primal,
                                                           old_theta(state, p.view)));
                v.restir_primal->commit(state);
            } else {
                render(view, theta, p.seed_primal, spp, s.image);
            }
            m_loss.evaluate(m_kind, s.image, v.reference, delta, mask, add);
            break;
        case CvMode::ps:
        case CvMode::pss: {
            const Buffer<float>& old = old_theta(state, p.view);
            if (m_cv == CvMode::ps) {
                render_two_state(view, theta, old, p.seed_primal, spp, s.image, s.image_old);
            } else {
                render(view, theta, p.seed_primal, spp, s.image);
                render(view, old, p.seed_primal, spp, s.image_old);
            }
            const std::string stats = state_name(k_cv_state, p.view);
            if (!state.has_buffer(stats))
                throw Error("parameter state: no buffer named '" + stats + "'");
            v.control->attach(state, stats); // its statistics are the state's
            v.control->evaluate(p.visit, m_kind, s.image, s.image_old, v.reference, delta, mask,
                                add);
            break;
        }
        }
    }
    // one scale for the batch, every view's replay into the one accumulator, one decode; over
    // several processes, the chunk sums of |delta| and the fixed-point words are exchanged
    // exactly in between (core/inverse/ranks.h)
    GradientBuffers& grad = state.gradient();
    const bool spread = m_ranks->size() > 1;
    const std::vector<const Buffer<float>*> deltas(m_last_deltas.begin(), m_last_deltas.end());
    std::vector<std::size_t> sizes;
    for (const ViewPass& p : batch) sizes.push_back(3 * tandem::View(m_scene, sensor(p.view)).pixels());
    std::function<void(std::vector<float>&)> exchange;
    if (spread) exchange = [this](std::vector<float>& sums) { m_ranks->gather_values(sums); };
    choose_gradient_scale(m_scene, deltas, grad, sizes, exchange);
    for (std::size_t b = 0; b < batch.size(); ++b) {
        const ViewPass& p = batch[b];
        if (!m_ranks->owns(p.view)) continue;
        ViewState& v = m_views.at(p.view);
        const tandem::View view(m_scene, v.sensor);
        const Buffer<float>& delta = *m_last_deltas[b];
        if (!v.restir) {
            accumulate_gradients(view, theta, p.seed_adjoint, spp_grad, delta, grad, {},
                                 m_boundary);
            continue;
        }
        accumulate_gradients(view, theta, p.seed_adjoint, spp_grad, delta, grad,
                             v.restir->resampled_by_paths(state, p.seed_restir,
                                                          old_theta(state, p.view)),
                             m_boundary);
        v.restir->commit(state);
    }
    if (spread) {
        std::vector<std::uint32_t> words = grad.fixed.download();
        m_ranks->sum_fixed(words);
        grad.fixed.upload(words);
        if (!m_ranks->root() && m_uncounted.size() == 0)
            m_uncounted = Buffer<unsigned>(m_scene.context(), "uncounted wraps", 1);
    }
    decode_gradients(m_scene, grad, spread && !m_ranks->root() ? &m_uncounted : nullptr);
    // each view's next visit compares with the parameters it was rendered with now
    if (m_batch < m_views.size())
        for (const ViewPass& p : batch) old_theta(state, p.view).copy_from(theta);
}

float GradientStep::loss() {
    std::vector<float> losses(m_last_batch, 0.0f); // each slot's, in the batch's order
    if (!m_own_slots.empty()) {
        const std::vector<float> own = m_loss.values();
        for (std::size_t i = 0; i < m_own_slots.size(); ++i) losses.at(m_own_slots[i]) = own.at(i);
    }
    m_ranks->gather_values(losses);
    return sum_losses(losses);
}

Buffer<float>& GradientStep::delta(unsigned slot) {
    Buffer<float>* d = m_last_deltas.at(slot);
    if (!d) throw Error("the view in slot " + std::to_string(slot) + " is another process's");
    return *d;
}

std::vector<std::string> GradientStep::view_state(unsigned view) const {
    const ViewState& v = m_views.at(view);
    std::vector<std::string> names;
    if (v.control) names.push_back(state_name(k_cv_state, view));
    for (const Restir* r : {v.restir.get(), v.restir_primal.get()})
        if (r) names.push_back(r->state_buffer());
    return names;
}

void GradientStep::warm_up(ParamState& state) {
    Context& ctx = m_scene.context();
    const Buffer<float>& theta = state.theta();
    ViewState& v = m_views.front();
    const tandem::View view(m_scene, v.sensor);
    Scratch& s = scratch(view.pixels());
    Buffer<float>& delta = slot_delta(0, 3 * view.pixels()); // the next evaluation writes it anew
    render(view, theta, 0xFFFFFFFFu, 1, s.image);
    if (m_cv == CvMode::ps)
        render_two_state(view, theta, theta, 0xFFFFFFFFu, 1, s.image, s.image_old);
    m_loss.evaluate(m_kind, s.image, v.reference, delta);
    Buffer<gpu::CvState> scratch_state(
        ctx, "scratch state", std::vector<gpu::CvState>(s.image.size(), gpu::cv_state_zero()));
    m_loss.evaluate_cv(m_kind, s.image, s.image, scratch_state, make_cv_config(0, m_cv_variance),
                       v.reference, delta);
    Buffer<float> alpha(ctx, "scratch alpha", s.image.size());
    m_loss.cv_alpha(scratch_state, alpha);
    if (v.mask.size()) m_loss.evaluate(m_kind, s.image, v.reference, delta, &v.mask);
    // the gradient of the warm-up goes to scratch buffers, not to the state's
    GradientBuffers grad(ctx, m_scene.param_count());
    backward(view, theta, 0xFFFFFFFFu, 1, delta, grad);
    // Each chain's pass on its own (as burn-in runs it) and fused into its paths (as an iteration
    // does): PoCL compiles a kernel at its first launch, which must not fall into the timed
    // burn-in. They write the chain's scratch reservoirs only; the state's are read.
    if (v.restir) {
        v.restir->resample(state, 0xFFFFFFFFu, 0xFFFFFFFFu);
        backward(view, theta, 0xFFFFFFFFu, v.restir->spp(), delta, grad,
                 v.restir->resampled_by_paths(state, 0xFFFFFFFFu));
    }
    if (v.restir_primal) {
        v.restir_primal->resample(state, 0xFFFFFFFFu, 0xFFFFFFFFu);
        render(view, theta, 0xFFFFFFFFu, v.restir_primal->spp(), s.image,
               v.restir_primal->resampled_by_paths(state, 0xFFFFFFFFu));
    }
    ctx.finish();
    m_scene.reset_guards();
}

} // namespace tandem
