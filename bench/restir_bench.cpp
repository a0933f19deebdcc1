// ReSTIR in the adjoint against plain PRB and RIS, at equal device time.
#include "bench/restir_bench.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <iostream>
#include <map>

#include "bench/restir_case.h"
#include "bench/restir_stats.h"
#include "runtime/error.h"

namespace tandem {

namespace {

using namespace restir_bench;

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
    const bool shapes = CaseRun::load(o, {"headline", o.scene, o.param, o.defines, {}})
                            .params.find(o.param)
                            .moves_geometry();
    const std::string control_scene =
        !o.control_scene.empty() ? o.control_scene
                                 : std::string(TANDEM_BENCH_SCENE_DIR) +
                                       (shapes ? "/shadow-one-light.xml" : "/indirect-room.xml");
    const std::string control_param = !o.control_param.empty() ? o.control_param
                                      : shapes                 ? o.param
                                                               : "painting.reflectance";
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
        specs.push_back({"negative_control", control_scene, control_param, {}, {last}});
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
        rc.shapes = run.shapes();
        say(spec.name + ": ReSTIR and RIS chains at spp " + std::to_string(o.spp_grad));
        std::map<int, Grads> restir_boundary;
        std::map<int, Grads> restir = run.chain(defaults, o.spp_grad, spec.ts, seeds, &restir_boundary);
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
            if (run.shapes()) {
                // the boundary terms alone, with the same samples as the whole gradients above,
                // against a reference of their own (RestirPoint::boundary_ratio)
                const RestirReference bref = run.reference(t, spp_ref, chunks, true);
                const Stages& r = times[0];
                const Stages& p = times[3];
                pt.estimates.push_back(estimate("restir_boundary",
                                                "ReSTIR's boundary terms", o.spp_grad, t, 0,
                                                {0, 0, r.boundary},
                                                run.reuses_boundary(defaults)
                                                    ? restir_boundary.at(t)
                                                    : run.boundary(o.spp_grad, t, seeds),
                                                bref));
                pt.estimates.push_back(estimate("prb_boundary",
                                                "plain PRB's boundary terms", spp_prb, t, 0,
                                                {0, 0, p.boundary}, run.boundary(spp_prb, t, seeds), bref));
                pt.boundary_reference_floor = bref.floor;
            }
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
