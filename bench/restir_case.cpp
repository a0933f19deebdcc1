// One case of `tandem bench restir` on the device (bench/restir_case.h).
#include "bench/restir_case.h"

#include <algorithm>
#include <iterator>
#include <limits>
#include <memory>

#include "core/inverse/gradient_step.h"
#include "core/inverse/optimizer.h"
#include "core/render/passes.h"
#include "runtime/error.h"

namespace tandem::restir_bench {

namespace {

Stages stages(Context& ctx) {
    const std::vector<StageTime> t = ctx.stage_times();
    return {stage_seconds(t, "restir"), stage_seconds(t, "adjoint"), stage_seconds(t, "boundary")};
}

SessionOptions reuse_options() {
    SessionOptions so;
    so.restir = true;
    return so;
}

} // namespace

std::vector<Stages> interleave(const std::vector<Timer>& timers, int rounds) {
    std::vector<Stages> best(timers.size());
    for (int r = 0; r < rounds; ++r)
        for (std::size_t i = 0; i < timers.size(); ++i) {
            const Stages s = timers[i]();
            if (r == 0 || s.iteration() < best[i].iteration()) best[i] = s;
        }
    return best;
}

RestirConfig ris_config() {
    RestirConfig c;
    c.candidates = 32;
    c.temporal = false;
    c.spatial = 0;
    c.burn_in = 0;
    return c;
}

std::vector<std::uint32_t> seed_list(std::uint32_t base, int count) {
    std::vector<std::uint32_t> s;
    for (int k = 0; k < count; ++k)
        s.push_back(base + std::uint32_t(k));
    return s;
}

CaseRun::CaseRun(Context& ctx, const KernelLibrary& lib, const RestirBenchOptions& o,
                 const CaseSpec& spec)
    : m_ctx(ctx), m_o(o), m_spec(spec), m_plain_session(ctx, lib, load(o, spec)),
      m_reuse_session(ctx, lib, load(o, spec), reuse_options()),
      m_scene(m_plain_session.scene()), m_plain(m_plain_session.device_scene()),
      m_reuse(m_reuse_session.device_scene()), m_p(m_scene.params.find(spec.param)),
      m_blocks(m_p.size, m_p.width, m_p.height, 3) { // element by element unless a texture
    const std::string why = restir_unsupported(m_scene);
    if (!why.empty()) throw Error(spec.scene + ": ReSTIR cannot run here: " + why);
    if (shapes())
        record_motion();
    else
        record_trajectory(lib);
    ImageLoss loss(ctx, lib);
    Buffer<float> image(ctx, "image", 3 * m_plain.pixels(0)), target(ctx, "target", m_target);
    for (int t : spec.ts) {
        Buffer<float> theta(ctx, "theta_t", m_thetas[t]);
        render(m_plain, theta, primal_seed(k_delta_seed, t), o.delta_spp, image);
        m_delta[t] = Buffer<float>(ctx, "delta_t", 3 * m_plain.pixels(0));
        loss.evaluate(LOSS_L2, image, target, m_delta[t]);
        m_loss[t] = loss.value();
    }
    // PoCL compiles a kernel at its first launch: not inside a timed pass
    prb(1, spec.ts[0], {k_timing_seed});
    RestirConfig warm = ris_config();
    warm.candidates = 1;
    chain(warm, 1, {spec.ts[0]}, {k_timing_seed});
    m_plain.reset_guards();
    m_reuse.reset_guards();
}

Grads CaseRun::prb(int spp, int t, const std::vector<std::uint32_t>& seeds) {
    Buffer<float> theta(m_ctx, "theta_t", m_thetas[t]);
    GradientBuffers grad(m_ctx, m_plain.param_count());
    grad.differentiate_only({{m_p.offset, m_p.size}});
    Grads g;
    for (std::uint32_t seed : seeds) {
        backward(m_plain, theta, adjoint_seed(seed, t), spp, m_delta.at(t), grad);
        g.push_back(download(grad));
    }
    return g;
}

Grads CaseRun::boundary(int spp, int t, const std::vector<std::uint32_t>& seeds) {
    Buffer<float> theta(m_ctx, "theta_t", m_thetas[t]);
    GradientBuffers grad(m_ctx, m_plain.param_count());
    grad.differentiate_only({{m_p.offset, m_p.size}});
    const Buffer<float>& delta = m_delta.at(t);
    Grads g;
    for (std::uint32_t seed : seeds) {
        // backward()'s steps, its interior pass left out
        choose_gradient_scale(m_plain, {&delta}, grad);
        prepare_shape_passes(m_plain, grad, {});
        m_plain.sync_geometry(theta);
        accumulate_boundary(View(m_plain), theta, adjoint_seed(seed, t), spp, delta, grad);
        decode_gradients(m_plain, grad);
        g.push_back(download(grad));
    }
    return g;
}

Timer CaseRun::prb_timer(int spp, int t) {
    auto theta = std::make_shared<Buffer<float>>(m_ctx, "theta_t", m_thetas[t]);
    auto grad = std::make_shared<GradientBuffers>(m_ctx, m_plain.param_count());
    grad->differentiate_only({{m_p.offset, m_p.size}});
    return [this, theta, grad, spp, t] {
        m_ctx.stage_times();
        backward(m_plain, *theta, adjoint_seed(k_timing_seed, t), spp, m_delta.at(t), *grad);
        return stages(m_ctx);
    };
}

bool CaseRun::reuses_boundary(const RestirConfig& config) const {
    return shapes() && m_o.boundary_reuse && (config.temporal || config.spatial > 0);
}

std::vector<float> CaseRun::boundary_pass(const Buffer<float>& theta, std::uint32_t seed, int spp,
                                          int t, SecondaryReservoirs& reuse) {
    GradientBuffers grad(m_ctx, m_reuse.param_count());
    grad.differentiate_only({{m_p.offset, m_p.size}});
    // an iteration between those measured has no delta of its own: its nearest one serves, as
    // the reservoirs never read it (their targets do not depend on the loss) and its gradients
    // are not kept
    auto near = m_delta.lower_bound(t);
    const Buffer<float>& delta = (near == m_delta.end() ? std::prev(near) : near)->second;
    choose_gradient_scale(m_reuse, {&delta}, grad);
    prepare_shape_passes(m_reuse, grad, {});
    m_reuse.sync_geometry(theta);
    BoundarySamples b;
    b.reuse = &reuse;
    accumulate_boundary(View(m_reuse), theta, seed, spp, delta, grad, b);
    decode_gradients(m_reuse, grad);
    return download(grad);
}

Timer CaseRun::restir_timer(const RestirConfig& config, int spp, int t) {
    auto restir = std::make_shared<Restir>(m_reuse, config, spp);
    auto state = std::make_shared<ParamState>(m_ctx, m_scene.params);
    state->differentiate_only({&m_p});
    restir->attach(*state);
    const int prev = std::max(0, t - 1);
    state->theta_prev().upload(m_thetas[std::max(0, t - 2)]);
    state->theta().upload(m_thetas[prev]);
    restir->resample(*state, adjoint_seed(k_timing_seed, prev), restir_seed(k_timing_seed, prev));
    restir->commit(*state);
    // the boundary's reservoirs of theta_{t-1}, as the interior's
    std::shared_ptr<SecondaryReservoirs> reuse;
    if (reuses_boundary(config)) {
        reuse = std::make_shared<SecondaryReservoirs>(m_ctx, m_o.boundary);
        boundary_pass(state->theta(), adjoint_seed(k_timing_seed, prev), spp, prev, *reuse);
    }
    state->theta_prev().upload(m_thetas[prev]);
    state->theta().upload(m_thetas[t]);
    return [this, restir, state, reuse, spp, t] {
        m_ctx.stage_times();
        restir->resample(*state, adjoint_seed(k_timing_seed, t), restir_seed(k_timing_seed, t));
        // the iteration: the pass fused into the adjoint's first kernel (the same bits), and the
        // boundary terms with their reuse where it has any
        const Buffer<float>& delta = m_delta.at(t);
        GradientBuffers& grad = state->gradient();
        choose_gradient_scale(m_reuse, {&delta}, grad);
        BoundarySamples b;
        b.reuse = reuse.get();
        accumulate_gradients(View(m_reuse), state->theta(), adjoint_seed(k_timing_seed, t), spp,
                             delta, grad,
                             restir->resampled_by_paths(*state, restir_seed(k_timing_seed, t)), b);
        decode_gradients(m_reuse, grad);
        return stages(m_ctx);
    };
}

std::map<int, Grads> CaseRun::chain(const RestirConfig& config, int spp, const std::vector<int>& ts,
                                    const std::vector<std::uint32_t>& seeds,
                                    std::map<int, Grads>* boundary) {
    Restir restir(m_reuse, config, spp);
    const bool reuse = config.temporal || config.spatial > 0;
    const bool reuse_boundary = reuses_boundary(config);
    const int last = *std::max_element(ts.begin(), ts.end());
    std::map<int, Grads> out;
    for (std::uint32_t seed : seeds) {
        ParamState state(m_ctx, m_scene.params);
        state.differentiate_only({&m_p});
        restir.attach(state);
        state.theta().upload(m_thetas[0]);
        state.theta_prev().upload(m_thetas[0]);
        restir.burn_in(state, seed);
        SecondaryReservoirs secondary(m_ctx, m_o.boundary);
        for (int n = 0; n <= last; ++n) {
            const bool measured = std::find(ts.begin(), ts.end(), n) != ts.end();
            if (!reuse && !measured) continue;
            state.theta_prev().upload(m_thetas[std::max(0, n - 1)]);
            state.theta().upload(m_thetas[n]);
            restir.resample(state, adjoint_seed(seed, n), restir_seed(seed, n));
            if (reuse_boundary) {
                // the boundary terms every iteration, their reservoirs carried on; measured: the
                // interior beside them, with the same seeds as backward()'s
                const std::vector<float> b =
                    boundary_pass(state.theta(), adjoint_seed(seed, n), spp, n, secondary);
                if (measured) {
                    GradientBuffers& grad = state.gradient();
                    const Buffer<float>& delta = m_delta.at(n);
                    choose_gradient_scale(m_reuse, {&delta}, grad);
                    BoundarySamples none;
                    none.primary = none.secondary = 0;
                    accumulate_gradients(View(m_reuse), state.theta(), adjoint_seed(seed, n), spp,
                                         delta, grad, restir.reservoirs(), none);
                    decode_gradients(m_reuse, grad);
                    std::vector<float> g = download(grad);
                    for (std::size_t k = 0; k < g.size(); ++k) g[k] += b[k];
                    out[n].push_back(g);
                    if (boundary) (*boundary)[n].push_back(b);
                }
            } else if (measured) {
                backward(m_reuse, state.theta(), adjoint_seed(seed, n), spp, m_delta.at(n),
                         state.gradient(), restir.reservoirs());
                out[n].push_back(download(state.gradient()));
            }
            restir.commit(state);
            m_ctx.stage_times(); // the record stays short
        }
    }
    return out;
}

RestirReference CaseRun::reference(int t, int spp, int chunks, bool boundary_only) {
    std::vector<std::vector<float>> parts;
    for (int c = 0; c < chunks; ++c) {
        const std::vector<std::uint32_t> seed{k_reference_seed + std::uint32_t(c)};
        parts.push_back(boundary_only ? boundary(spp / chunks, t, seed)[0]
                                      : prb(spp / chunks, t, seed)[0]);
    }
    return make_reference(parts, m_blocks);
}

RenderScene CaseRun::load(const RestirBenchOptions& o, const CaseSpec& spec) {
    SceneDesc desc = load_scene(spec.scene, spec.defines);
    desc.camera().width = desc.camera().height = o.res;
    return build_render_scene(desc);
}

std::vector<float> CaseRun::download(GradientBuffers& grad) {
    std::vector<float> g(m_p.size);
    grad.value.enqueue_read(m_p.offset, m_p.size, g.data());
    m_ctx.finish();
    return g;
}

void CaseRun::record_trajectory(const KernelLibrary& lib) {
    RenderOptions ro;
    ro.spp = m_o.target_spp;
    ro.seed = stream_seed(k_train_seed, 0, Stream::target);
    m_target = m_plain_session.render_image(m_scene.params.values(), ro).rgb;
    std::vector<float> values = m_scene.params.values(), lr(values.size(), 0.0f);
    std::fill_n(values.begin() + m_p.offset, m_p.size, 0.5f);
    std::fill_n(lr.begin() + m_p.offset, m_p.size, m_o.lr);
    std::string reason;
    const CvMode plan = plan_cv(CvMode::ps, {&m_p}, &reason);
    GradientStep step(m_plain, lib, LOSS_L2, m_target, plan);
    ParamState state(m_ctx, m_scene.params);
    Optimizer adam(state, lib, OptimizerConfig{});
    step.attach(state);
    state.learning_rates().upload(lr);
    state.differentiate_only({&m_p});
    state.theta().upload(values);
    state.theta_prev().upload(values);
    m_thetas.push_back(values);
    const int last = *std::max_element(m_spec.ts.begin(), m_spec.ts.end());
    for (int it = 0; it < last; ++it) {
        const auto n = std::uint32_t(it);
        step.evaluate(state, n, primal_seed(k_train_seed, n), m_o.train_spp,
                      adjoint_seed(k_train_seed, n), m_o.train_spp);
        state.remember_theta();
        adam.step();
        m_thetas.push_back(state.theta().download());
    }
}

void CaseRun::record_motion() {
    RenderOptions ro;
    ro.spp = m_o.target_spp;
    ro.seed = stream_seed(k_train_seed, 0, Stream::target);
    const std::vector<float> goal = m_scene.params.values();
    m_target = m_plain_session.render_image(goal, ro).rgb;
    float lo[3], hi[3];
    std::fill_n(lo, 3, std::numeric_limits<float>::infinity());
    std::fill_n(hi, 3, -std::numeric_limits<float>::infinity());
    for (std::size_t j = 0; j < m_p.size; ++j) {
        lo[j % 3] = std::min(lo[j % 3], goal[m_p.offset + j]);
        hi[j % 3] = std::max(hi[j % 3], goal[m_p.offset + j]);
    }
    const float diagonal = std::hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
    const float offset = m_o.shape_offset * diagonal;
    const int last = *std::max_element(m_spec.ts.begin(), m_spec.ts.end());
    for (int t = 0; t <= last; ++t) {
        std::vector<float> values = goal;
        const float x = offset * (1.0f - 0.5f * float(t) / float(std::max(1, last)));
        for (std::size_t j = 0; j < m_p.size; j += 3)
            values[m_p.offset + j] += x;
        m_thetas.push_back(values);
    }
}

} // namespace tandem::restir_bench
