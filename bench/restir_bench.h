// `tandem bench restir`: the adjoint noise of ReSTIR light-sample reuse ("Amortizing Samples in
// Physics-Based Inverse Rendering using ReSTIR", Wang, Wyman, Wu, Zhao, SIGGRAPH Asia 2023)
// against plain PRB and against RIS without reuse, at equal device time.
//
// Protocol, per case (scene, parameter, max_depth):
//  1. One theta trajectory: Adam on the parameter from a flat 0.5 (L2 loss, PRB + CV-PS, as
//     scenes/gallery-lights-recover.json), against the scene itself rendered at target_spp.
//  2. At each measured iteration t, delta_t = dloss/dimage from a delta_spp primal render at
//     theta_t (L2 against the target), fixed: only the adjoint's noise is measured.
//  3. The reference g*: plain PRB at reference_factor x the largest estimator spp (at least
//     reference_min_spp: with a cheap pass the estimators' spp are small), same delta_t,
//     as the mean of reference_chunks independent passes (their spread gives its own noise).
//  4. Estimators at theta_t, each over `seeds` seeds: ReSTIR (the default RestirConfig; burn-in
//     at theta_0, then the resampling passes of iterations 0..t over the recorded trajectory,
//     then the adjoint at t), RIS (candidates 32, no temporal or spatial reuse), plain PRB at the
//     ReSTIR's spp_grad, and plain PRB and RIS with their spp raised to ReSTIR's device time.
//  5. Time: device seconds of the stages "restir" + "adjoint" of one iteration at t, the best of
//     interleaved rounds of every estimator; ReSTIR's burn-in counts its passes at the resampling
//     pass's time, divided by t. Error: relMSE = mean over elements of (g - g*)^2 / (g*^2 + eps),
//     eps = 1e-2 mean(g*^2), and ||g - g*|| / ||g*||, averaged over the seeds; and two bias
//     checks (bench/restir_stats.h).
#pragma once

#include "core/render/boundary_reuse.h"
#include "runtime/tuning.h"

#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace tandem {

struct RestirBenchOptions {
    std::string scene = TANDEM_BENCH_SCENE_DIR "/gallery-lights.xml";
    std::string param = "painting.reflectance";
    std::vector<std::pair<std::string, std::string>> defines; ///< scene defines (-D)
    /// The negative control: where reuse has little to gain. Empty: for a material parameter,
    /// indirect-room.xml (its light reaches the parameter only indirectly) and
    /// painting.reflectance; for a mesh's vertex positions, shadow-one-light.xml (one large
    /// light) and the same parameter.
    std::string control_scene, control_param;
    /// A mesh's trajectory starts translated by this times its bounding box's diagonal
    /// (bench/restir_case.h).
    float shape_offset = 0.05f;
    /// For vertex positions, ReSTIR reuses the secondary boundary term's light vertices too
    /// (core/render/boundary_reuse.h), with `boundary`; RIS and PRB never do.
    bool boundary_reuse = true;
    SecondaryReuseConfig boundary;
    int deep_depth = 5;         ///< max_depth of the second headline case (-D max_depth=N)
    bool headline_only = false; ///< measure only the first case (no deeper case, no control)
    int res = 128;              ///< square film
    int seeds = 8;
    int spp_grad = 4;                      ///< ReSTIR's adjoint spp (and RIS' before matching)
    std::vector<int> iterations{1, 8, 32}; ///< t of the first case; the others use the last
    float lr = 0.02f;                      ///< Adam's learning rate of the trajectory
    int train_spp = 4;                     ///< spp and spp_grad of the trajectory
    int target_spp = 256;
    int delta_spp = 256;
    int reference_factor = 64;
    /// Fewer reference samples leave the reference's own noise in every relMSE. At 2048 the
    /// reference does not depend on the equal-time spp (so not on the machine's load) while those
    /// stay at 32 or below, and runs compare.
    int reference_min_spp = 2048;
    int reference_chunks = 8;
    /// the share of direct light ReSTIR and RIS estimate (RestirConfig::direct): auto, all, mis
    std::string direct = "auto";
    bool ablations = false;
    int ablation_seeds = 0; ///< 0: seeds
    std::string device;
    Tuning tuning; ///< the switches, as the entry point read them (runtime/tuning.h)
    bool progress = false;
};

/// One estimator at one t.
struct RestirEstimate {
    std::string name;   ///< prb, prb_equal_spp, ris, ris_equal_spp, restir, or an ablation
    std::string config; ///< what it is, in words
    int spp = 0;
    double seconds = 0; ///< device s per iteration: adjoint + burn-in / t
    /// one resampling pass on its own at iteration t: what each burn-in pass costs
    double restir_seconds = 0;
    /// the adjoint of iteration t, with its resampling pass fused into it
    double adjoint_seconds = 0;
    double burn_in_seconds = 0; ///< the whole burn-in (median over seeds)
    int seeds = 0;
    double relmse = 0, relmse_se = 0, rel_l2 = 0;
    /// Bias checks. sum_j g_j (the derivative along all elements at once): the mean over seeds
    /// over the reference's, and z = (mean - reference) / the standard error of the two.
    double sum_ratio = 0, sum_z = 0;
    /// The same z per block of 16 x 16 texels (bench/restir_stats.h): its mean, mean |z| and the
    /// share beyond 3. Heavy tails push the last two up without any bias, so plain PRB's
    /// values (exactly unbiased) are the calibration. Needs two seeds or more.
    double block_z_mean = 0, block_z_mean_abs = 0, block_z_beyond_3 = 0;
    nlohmann::json to_json() const;
};

struct RestirPoint {
    int t = 0;
    double loss = 0; ///< the L2 loss of the delta_spp render at theta_t
    int reference_spp = 0;
    double eps = 0;
    /// relMSE of the reference itself (its chunks' spread), part of every estimator's relMSE
    double reference_floor = 0, reference_rel_l2 = 0;
    /// For shapes: the boundary reference's own relMSE
    double boundary_reference_floor = 0;
    /// For shapes, besides the whole gradients' estimators: restir_boundary and prb_boundary, the
    /// boundary terms alone of restir and prb (same samples), against a boundary reference.
    std::vector<RestirEstimate> estimates;
    const RestirEstimate* find(const std::string& name) const;
    /// relMSE(base) / relMSE(of) at the spp each has here.
    double ratio(const std::string& base, const std::string& of = "restir") const;
    /// The standard error of ratio() from the two relMSEs' (first order).
    double ratio_se(const std::string& base) const;
    /// The same with the reference's own noise subtracted from both.
    double ratio_corrected(const std::string& base) const;
    /// (relMSE x seconds)(base) / (relMSE x seconds)(restir).
    double efficiency(const std::string& base) const;
    nlohmann::json to_json() const;
};

struct RestirCase {
    std::string name, scene, param;
    std::vector<std::pair<std::string, std::string>> defines; ///< the scene's -D, in order
    int max_depth = 0;
    bool shapes = false; ///< the parameter moves geometry (a mesh's vertex positions)
    std::vector<RestirPoint> points;
    const RestirPoint* at(int t) const;
    nlohmann::json to_json() const;
};

struct RestirBenchResult {
    std::string device;
    int res = 0, seeds = 0, spp_grad = 0, delta_spp = 0, target_spp = 0, reference_factor = 0;
    std::vector<RestirCase> cases;
    int ablation_t = 0;
    std::vector<RestirEstimate> ablations; ///< at ablation_t of the first case
    double wall_seconds = 0;
    nlohmann::json to_json() const;
    std::string to_table() const;
};

RestirBenchResult run_restir_bench(const RestirBenchOptions& options);

} // namespace tandem
