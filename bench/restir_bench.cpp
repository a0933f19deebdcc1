// ReSTIR in the adjoint against plain PRB and RIS, at equal device time.
#include "bench/restir_bench.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <iostream>
#include <map>

#include "bench/restir_stats.h"
#include "core/inverse/gradient_step.h"
#include "core/inverse/optimizer.h"
#include "core/inverse/session.h"
#include "runtime/error.h"

namespace tandem {

namespace {

constexpr std::uint32_t k_train_seed = 0;              ///< the trajectory's (tandem optimize's)
constexpr std::uint32_t k_seed_base = 1000;            ///< estimator seed k: 1000 + k
constexpr std::uint32_t k_reference_seed = 0x5EED0000; ///< reference chunk c: this + c
constexpr std::uint32_t k_timing_seed = 0x71A10000;    ///< spp matching runs
constexpr std::uint32_t k_delta_seed = 0x0DE17A00;
constexpr int k_timing_rounds = 5;

struct CaseSpec {
    std::string name, scene, param;
    std::vector<std::pair<std::string, std::string>> defines;
    std::vector<int> ts;
};

/// The gradients (the parameter's elements) of one estimator, one per seed.
using Grads = std::vector<std::vector<float>>;

/// Device seconds of one timed iteration's stages. ReSTIR's iteration runs its resampling pass
/// fused into the adjoint's first kernel, as tandem optimize does (docs/restir.md, "One pass
/// fewer"): `adjoint` is the whole iteration. `restir` is one resampling pass on its own, timed
/// beside it: what each burn-in pass costs (0 for plain PRB).
struct Stages {
    double restir = 0, adjoint = 0;
    double iteration() const { return adjoint; }
};
/// Enqueues one timed iteration and returns its stage times.
using Timer = std::function<Stages()>;

Stages stages(Context& ctx) {
    const std::vector<StageTime> t = ctx.stage_times();
    return {stage_seconds(t, "restir"), stage_seconds(t, "adjoint")};
}

/// The fastest of `rounds` runs of each timer, run in interleaved rounds (load on a shared
/// machine only ever adds time, and hits every timer alike).
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

/// One case on the device: its scene (plain and with RESTIR=1), trajectory and deltas.
class CaseRun {
public:
    CaseRun(Context& ctx, const KernelLibrary& lib, const RestirBenchOptions& o,
            const CaseSpec& spec)
        : m_ctx(ctx), m_o(o), m_spec(spec), m_plain_session(ctx, lib, load(o, spec)),
          m_reuse_session(ctx, lib, load(o, spec), reuse_options()),
          m_scene(m_plain_session.scene()), m_plain(m_plain_session.device_scene()),
          m_reuse(m_reuse_session.device_scene()),
          m_p(m_scene.params.find(spec.param)),
          m_blocks(m_p.size, m_p.width, m_p.height, 3) { // element by element unless a texture
        const std::string why = restir_unsupported(m_scene);
        if (!why.empty()) throw Error(spec.scene + ": ReSTIR cannot run here: " + why);
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

    const RenderScene& scene() const { return m_scene; }
    double loss(int t) const { return m_loss.at(t); }
    std::uint64_t guards() { return m_plain.read_guards() + m_reuse.read_guards(); }

    /// Plain PRB at theta_t with `spp` per seed.
    Grads prb(int spp, int t, const std::vector<std::uint32_t>& seeds) {
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

    /// One timed plain PRB adjoint at theta_t.
    Timer prb_timer(int spp, int t) {
        auto theta = std::make_shared<Buffer<float>>(m_ctx, "theta_t", m_thetas[t]);
        auto grad = std::make_shared<GradientBuffers>(m_ctx, m_plain.param_count());
        grad->differentiate_only({{m_p.offset, m_p.size}});
        return [this, theta, grad, spp, t] {
            m_ctx.stage_times();
            backward(m_plain, *theta, adjoint_seed(k_timing_seed, t), spp, m_delta.at(t), *grad);
            return stages(m_ctx);
        };
    }

    /// One timed iteration t with `config`: the adjoint with the resampling pass fused into it,
    /// and beside it the same pass on its own (Stages). The previous reservoirs come from one
    /// untimed pass at theta_{t-1}, so that neighbours are there.
    Timer restir_timer(const RestirConfig& config, int spp, int t) {
        auto restir = std::make_shared<Restir>(m_reuse, config, spp);
        auto state = std::make_shared<ParamState>(m_ctx, m_scene.params);
        state->differentiate_only({&m_p});
        restir->attach(*state);
        const int prev = std::max(0, t - 1);
        state->theta_prev().upload(m_thetas[std::max(0, t - 2)]);
        state->theta().upload(m_thetas[prev]);
        restir->resample(*state, adjoint_seed(k_timing_seed, prev),
                         restir_seed(k_timing_seed, prev));
        restir->commit(*state);
        state->theta_prev().upload(m_thetas[prev]);
        state->theta().upload(m_thetas[t]);
        return [this, restir, state, spp, t] {
            m_ctx.stage_times();
            restir->resample(*state, adjoint_seed(k_timing_seed, t), restir_seed(k_timing_seed, t));
            // the iteration: the pass fused into the adjoint's first kernel (the same bits)
            backward(m_reuse, state->theta(), adjoint_seed(k_timing_seed, t), spp, m_delta.at(t),
                     state->gradient(),
                     restir->resampled_by_paths(*state, restir_seed(k_timing_seed, t)));
            return stages(m_ctx);
        };
    }

    /// ReSTIR with `config` at each t of `ts` per seed: burn-in at theta_0, then the resampling
    /// passes of iterations 0..t over the trajectory (theta_prev = theta_{n-1}), the adjoint at
    /// each t of `ts`. Without temporal or spatial reuse only the iterations of `ts` run.
    std::map<int, Grads> chain(const RestirConfig& config, int spp, const std::vector<int>& ts,
                               const std::vector<std::uint32_t>& seeds) {
        Restir restir(m_reuse, config, spp);
        const bool reuse = config.temporal || config.spatial > 0;
        const int last = *std::max_element(ts.begin(), ts.end());
        std::map<int, Grads> out;
        for (std::uint32_t seed : seeds) {
            ParamState state(m_ctx, m_scene.params);
            state.differentiate_only({&m_p});
            restir.attach(state);
            state.theta().upload(m_thetas[0]);
            state.theta_prev().upload(m_thetas[0]);
            restir.burn_in(state, seed);
            for (int n = 0; n <= last; ++n) {
                const bool measured = std::find(ts.begin(), ts.end(), n) != ts.end();
                if (!reuse && !measured) continue;
                state.theta_prev().upload(m_thetas[std::max(0, n - 1)]);
                state.theta().upload(m_thetas[n]);
                restir.resample(state, adjoint_seed(seed, n), restir_seed(seed, n));
                if (measured) {
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

    /// g* at t from `chunks` PRB passes of spp / chunks each.
    RestirReference reference(int t, int spp, int chunks) {
        std::vector<std::vector<float>> parts;
        for (int c = 0; c < chunks; ++c)
            parts.push_back(prb(spp / chunks, t, {k_reference_seed + std::uint32_t(c)})[0]);
        return make_reference(parts, m_blocks);
    }

    static SessionOptions reuse_options() {
        SessionOptions so;
        so.restir = true;
        return so;
    }

    static RenderScene load(const RestirBenchOptions& o, const CaseSpec& spec) {
        SceneDesc desc = load_scene(spec.scene, spec.defines);
        desc.camera().width = desc.camera().height = o.res;
        return build_render_scene(desc);
    }

private:
    std::vector<float> download(GradientBuffers& grad) {
        std::vector<float> g(m_p.size);
        grad.value.enqueue_read(m_p.offset, m_p.size, g.data());
        m_ctx.finish();
        return g;
    }

    /// Adam from a flat 0.5 with PRB + CV-PS against the scene at target_spp (the target and
    /// seeds of `tandem optimize` with seed 0): theta_0 .. theta_T.
    void record_trajectory(const KernelLibrary& lib) {
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

    Context& m_ctx;
    const RestirBenchOptions& m_o;
    CaseSpec m_spec;
    Session m_plain_session, m_reuse_session; ///< the scene plain and with RESTIR=1
    const RenderScene& m_scene;
    DeviceScene &m_plain, &m_reuse;
    const Parameter& m_p;
    RestirBlocks m_blocks;
    std::vector<float> m_target;
    std::vector<std::vector<float>> m_thetas; ///< theta_0 .. theta_T, the whole buffer
    std::map<int, Buffer<float>> m_delta;
    std::map<int, double> m_loss;
};

/// An estimator's error from its gradients, and its time: the resampling pass and the adjoint
/// of one iteration, and `burn_in` resampling passes of the same cost spread over t iterations.
RestirEstimate estimate(const std::string& name, const std::string& config, int spp, int t,
                        int burn_in, const Stages& time, const Grads& grads,
                        const RestirReference& ref) {
    RestirEstimate e;
    e.name = name;
    e.config = config;
    e.spp = spp;
    e.seeds = int(grads.size());
    e.restir_seconds = time.restir;
    e.adjoint_seconds = time.adjoint;
    e.burn_in_seconds = burn_in * time.restir;
    e.seconds = time.iteration() + e.burn_in_seconds / std::max(1, t);
    measure_estimate(grads, ref, &e);
    return e;
}

std::string describe(const RestirConfig& c) {
    auto num = [](double v) {
        if (v >= 1e29) return std::string("inf");
        std::string s = std::to_string(v);
        s.erase(s.find_last_not_of('0') + 1);
        if (s.back() == '.') s.pop_back();
        return s;
    };
    return "candidates " + std::to_string(c.candidates) + ", temporal " +
           (c.temporal ? "on" : "off") + ", spatial " + std::to_string(c.spatial) + ", m_cap " +
           num(c.m_cap) + ", burn_in " + std::to_string(c.burn_in) + ", visibility " +
           (c.visibility ? "on" : "off") + ", direct " + restir_direct_name(c.direct);
}

/// One setting changed at a time from `base` (the bench's ReSTIR config).
std::vector<std::pair<std::string, RestirConfig>> ablation_configs(const RestirConfig& base) {
    std::vector<std::pair<std::string, RestirConfig>> out;
    auto add = [&](const std::string& name, auto&& change) {
        RestirConfig c = base;
        change(c);
        out.emplace_back(name, c);
    };
    add("visibility off", [](RestirConfig& c) { c.visibility = false; });
    // the other share of direct light: all of it at a diffuse vertex, or NEE's MIS share
    // (docs/restir.md)
    const RestirDirect other =
        base.direct == RestirDirect::mis ? RestirDirect::automatic : RestirDirect::mis;
    add(std::string("direct ") + restir_direct_name(other),
        [other](RestirConfig& c) { c.direct = other; });
    for (int s : {0, 1, 4})
        add("spatial " + std::to_string(s), [s](RestirConfig& c) { c.spatial = s; });
    add("m_cap 5", [](RestirConfig& c) { c.m_cap = 5.0f; });
    add("m_cap inf", [](RestirConfig& c) { c.m_cap = 1e30f; });
    for (int m : {4, 32})
        add("candidates " + std::to_string(m), [m](RestirConfig& c) { c.candidates = m; });
    for (int b : {0, 32})
        add("burn_in " + std::to_string(b), [b](RestirConfig& c) { c.burn_in = b; });
    // no reuse at all, many candidates: how far light sampling alone can go at this spp
    add("no reuse, candidates 128", [&base](RestirConfig& c) {
        c = ris_config();
        c.direct = base.direct;
        c.candidates = 128;
    });
    return out;
}

} // namespace

RestirBenchResult run_restir_bench(const RestirBenchOptions& o) {
    const auto wall0 = std::chrono::steady_clock::now();
    if (o.iterations.empty() || *std::min_element(o.iterations.begin(), o.iterations.end()) < 1)
        throw Error("bench restir: the iterations must be at least 1");
    Context ctx = Context::create(o.device, o.tuning);
    ctx.set_stage_timing(true);
    const KernelLibrary& lib = KernelLibrary::from_tuning(o.tuning);
    RestirBenchResult result;
    result.device = ctx.device().name;
    result.res = o.res;
    result.seeds = o.seeds;
    result.spp_grad = o.spp_grad;
    result.delta_spp = o.delta_spp;
    result.target_spp = o.target_spp;
    result.reference_factor = o.reference_factor;
    auto say = [&](const std::string& what) {
        if (!o.progress) return;
        const double s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
        std::cerr << "[" << int(s) << " s] " << what << std::endl;
    };

    const int last = *std::max_element(o.iterations.begin(), o.iterations.end());
    std::vector<CaseSpec> specs{{"headline", o.scene, o.param, o.defines, o.iterations}};
    if (!o.headline_only) {
        auto deep = o.defines; // the scene's -D, with its max_depth replaced by --deep-depth
        deep.erase(std::remove_if(deep.begin(), deep.end(),
                                  [](const auto& d) { return d.first == "max_depth"; }),
                   deep.end());
        deep.emplace_back("max_depth", std::to_string(o.deep_depth));
        if (o.deep_depth > 0)
            specs.push_back(
                {"depth" + std::to_string(o.deep_depth), o.scene, o.param, deep, {last}});
        specs.push_back({"negative_control", o.control_scene, o.control_param, {}, {last}});
    }
    for (const CaseSpec& spec : specs) { // bad names fail now, not after minutes of work
        const RenderScene scene = CaseRun::load(o, spec);
        scene.params.find(spec.param);
    }
    const std::vector<std::uint32_t> seeds = seed_list(k_seed_base, o.seeds);
    RestirConfig defaults, ris = ris_config();
    defaults.direct = ris.direct = restir_direct(o.direct);
    const int rounds = k_timing_rounds;
    for (std::size_t ci = 0; ci < specs.size(); ++ci) {
        const CaseSpec& spec = specs[ci];
        say(spec.name + ": trajectory and deltas (" + spec.scene + ")");
        CaseRun run(ctx, lib, o, spec);
        RestirCase rc;
        rc.name = spec.name;
        rc.scene = spec.scene;
        rc.defines = spec.defines;
        rc.param = spec.param;
        rc.max_depth = run.scene().max_depth;
        say(spec.name + ": ReSTIR and RIS chains at spp " + std::to_string(o.spp_grad));
        std::map<int, Grads> restir = run.chain(defaults, o.spp_grad, spec.ts, seeds);
        std::map<int, Grads> ris_grads = run.chain(ris, o.spp_grad, spec.ts, seeds);
        std::map<int, RestirReference> references;
        std::map<int, Stages> restir_time;
        for (int t : spec.ts) {
            // Equal time: PRB's and RIS' spp raised until their iteration takes ReSTIR's device
            // time (burn-in spread over t) within 10 %, all timed in interleaved rounds.
            const Timer t_restir = run.restir_timer(defaults, o.spp_grad, t);
            const Timer t_prb4 = run.prb_timer(o.spp_grad, t);
            const Timer t_ris4 = run.restir_timer(ris, o.spp_grad, t);
            int spp_prb = o.spp_grad, spp_ris = o.spp_grad;
            std::vector<Stages> times;
            double target = 0.0;
            for (int pass = 0;; ++pass) {
                times = interleave({t_restir, t_prb4, t_ris4, run.prb_timer(spp_prb, t),
                                    run.restir_timer(ris, spp_ris, t)},
                                   rounds);
                target = times[0].iteration() + defaults.burn_in * times[0].restir / double(t);
                auto next = [&](int spp, const Stages& s) {
                    return std::fabs(s.iteration() / target - 1.0) <= 0.1
                               ? spp
                               : std::max(1, int(std::lround(spp * target / s.iteration())));
                };
                const int np = next(spp_prb, times[3]), nr = next(spp_ris, times[4]);
                if (pass == 3 || (np == spp_prb && nr == spp_ris)) break;
                spp_prb = np, spp_ris = nr;
            }
            restir_time[t] = times[0];
            say(spec.name + " t=" + std::to_string(t) + ": equal time at PRB spp " +
                std::to_string(spp_prb) + ", RIS spp " + std::to_string(spp_ris));
            const Grads prb_equal_spp = run.prb(o.spp_grad, t, seeds);
            const Grads prb = run.prb(spp_prb, t, seeds);
            const Grads ris_matched =
                spp_ris == o.spp_grad ? ris_grads.at(t) : run.chain(ris, spp_ris, {t}, seeds).at(t);
            const int chunks = std::max(1, o.reference_chunks);
            int spp_ref = std::max(o.reference_min_spp,
                                   o.reference_factor * std::max({spp_prb, spp_ris, o.spp_grad}));
            spp_ref = (spp_ref + chunks - 1) / chunks * chunks;
            say(spec.name + " t=" + std::to_string(t) + ": reference at " +
                std::to_string(spp_ref) + " spp");
            references[t] = run.reference(t, spp_ref, chunks);
            const RestirReference& ref = references[t];
            RestirPoint pt;
            pt.t = t;
            pt.loss = run.loss(t);
            pt.reference_spp = spp_ref;
            pt.eps = ref.eps;
            pt.reference_floor = ref.floor;
            pt.reference_rel_l2 = ref.rel_l2;
            pt.estimates = {estimate("restir", "ReSTIR: " + describe(defaults), o.spp_grad, t,
                                     defaults.burn_in, times[0], restir.at(t), ref),
                            estimate("prb", "plain PRB, spp raised to ReSTIR's time", spp_prb, t, 0,
                                     times[3], prb, ref),
                            estimate("ris", "RIS without reuse, spp raised to ReSTIR's time",
                                     spp_ris, t, 0, times[4], ris_matched, ref),
                            estimate("prb_equal_spp", "plain PRB at ReSTIR's spp", o.spp_grad, t, 0,
                                     times[1], prb_equal_spp, ref),
                            estimate("ris_equal_spp", "RIS: " + describe(ris), o.spp_grad, t, 0,
                                     times[2], ris_grads.at(t), ref)};
            rc.points.push_back(pt);
            say(spec.name + " t=" + std::to_string(t) + ": relMSE PRB / ReSTIR " +
                std::to_string(pt.ratio("prb")) + ", RIS / ReSTIR " +
                std::to_string(pt.ratio("ris")));
        }
        if (ci == 0 && o.ablations) {
            // Each variant at the last t on the first seeds, timed side by side with the default
            // (its time: the ratio of the two, times the default's time above).
            const int t = last;
            const int count = o.ablation_seeds > 0 ? std::min(o.ablation_seeds, o.seeds) : o.seeds;
            const std::vector<std::uint32_t> aseeds = seed_list(k_seed_base, count);
            const RestirReference& ref = references.at(t);
            const Stages& base = restir_time.at(t);
            result.ablation_t = t;
            Grads first(restir.at(t).begin(), restir.at(t).begin() + count);
            result.ablations.push_back(estimate("default", describe(defaults), o.spp_grad, t,
                                                defaults.burn_in, base, first, ref));
            const Timer t_default = run.restir_timer(defaults, o.spp_grad, t);
            for (const auto& [name, config] : ablation_configs(defaults)) {
                say("ablation " + name);
                const Grads g = run.chain(config, o.spp_grad, {t}, aseeds).at(t);
                const std::vector<Stages> side =
                    interleave({t_default, run.restir_timer(config, o.spp_grad, t)}, rounds);
                const double scale = base.iteration() / side[0].iteration();
                const Stages time{side[1].restir * scale, side[1].adjoint * scale};
                result.ablations.push_back(
                    estimate(name, describe(config), o.spp_grad, t, config.burn_in, time, g, ref));
            }
        }
        const std::uint64_t guards = run.guards();
        if (guards)
            std::cerr << "warning: " << spec.name << ": " << guards
                      << " non-finite samples or weights, saturated or wrapped gradient sums\n";
        result.cases.push_back(rc);
    }
    result.wall_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    return result;
}

} // namespace tandem
