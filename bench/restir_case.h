// One case of `tandem bench restir` (bench/restir_bench.h) on the device: its scene plain and with
// reservoirs, the recorded theta trajectory and fixed deltas, and each estimator's gradients over
// seeds and its timed iteration.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "bench/restir_bench.h"
#include "bench/restir_stats.h"
#include "core/inverse/restir.h"
#include "core/inverse/session.h"

namespace tandem::restir_bench {

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
/// fewer"): `adjoint` holds it. `restir` is one resampling pass on its own, timed beside it: what
/// each burn-in pass costs (0 for plain PRB). `boundary`: the boundary terms of shape gradients.
struct Stages {
    double restir = 0, adjoint = 0, boundary = 0;
    double iteration() const { return adjoint + boundary; }
};
/// Enqueues one timed iteration and returns its stage times.
using Timer = std::function<Stages()>;

/// The fastest of `rounds` runs of each timer, run in interleaved rounds (load on a shared
/// machine only ever adds time, and hits every timer alike).
std::vector<Stages> interleave(const std::vector<Timer>& timers, int rounds);

/// RIS without reuse: 32 candidates, no temporal or spatial reuse.
RestirConfig ris_config();

/// base, base + 1, ..., base + count - 1
std::vector<std::uint32_t> seed_list(std::uint32_t base, int count);

/// One case on the device: its scene (plain and with RESTIR=1), trajectory and deltas.
///
/// The trajectory: for a material or emitter parameter, Adam from a flat 0.5 with PRB + CV-PS
/// against the scene itself (the target and seeds of `tandem optimize` with seed 0). For a mesh's
/// vertex positions, the mesh translated rigidly from `shape_offset` times its bounding box's
/// diagonal along +x toward where the scene has it, at a constant speed that covers half the way
/// by the last measured iteration: the path of an optimizer that follows the gradient perfectly,
/// without the crumpling that Adam on raw vertices gives (Large Steps would smooth it; the reuse
/// sees the same change of theta per iteration either way).
class CaseRun {
public:
    CaseRun(Context& ctx, const KernelLibrary& lib, const RestirBenchOptions& o,
            const CaseSpec& spec);

    const RenderScene& scene() const { return m_scene; }
    /// Whether the parameter moves geometry: the gradients then have boundary terms.
    bool shapes() const { return m_p.moves_geometry(); }
    double loss(int t) const { return m_loss.at(t); }
    std::uint64_t guards() { return m_plain.read_guards() + m_reuse.read_guards(); }

    /// Plain PRB at theta_t with `spp` per seed (the boundary terms, for shapes, at spp too).
    Grads prb(int spp, int t, const std::vector<std::uint32_t>& seeds);
    /// The boundary terms of the shape gradient alone, as prb() computes them for the same seeds.
    Grads boundary(int spp, int t, const std::vector<std::uint32_t>& seeds);
    /// One timed plain PRB iteration at theta_t.
    Timer prb_timer(int spp, int t);
    /// One timed iteration t with `config`: the adjoint with the resampling pass fused into it,
    /// and beside it the same pass on its own (Stages). The previous reservoirs come from one
    /// untimed pass at theta_{t-1}, so that neighbours are there.
    Timer restir_timer(const RestirConfig& config, int spp, int t);
    /// ReSTIR with `config` at each t of `ts` per seed: burn-in at theta_0, then the resampling
    /// passes of iterations 0..t over the trajectory (theta_prev = theta_{n-1}), the adjoint at
    /// each t of `ts`. Without temporal or spatial reuse only the iterations of `ts` run.
    /// For vertex positions with boundary reuse (reuses_boundary), every iteration runs the
    /// boundary terms, whose reservoirs carry on, and `boundary` (if set) gets them alone at each
    /// t of `ts`.
    std::map<int, Grads> chain(const RestirConfig& config, int spp, const std::vector<int>& ts,
                               const std::vector<std::uint32_t>& seeds,
                               std::map<int, Grads>* boundary = nullptr);
    /// Whether ReSTIR with `config` reuses the secondary boundary term's light vertices too: for
    /// vertex positions, with --boundary-reuse, where `config` reuses at all.
    bool reuses_boundary(const RestirConfig& config) const;
    /// g* at t from `chunks` PRB passes of spp / chunks each; with `boundary_only`, of the
    /// boundary terms alone (boundary()).
    RestirReference reference(int t, int spp, int chunks, bool boundary_only = false);

    static RenderScene load(const RestirBenchOptions& o, const CaseSpec& spec);

private:
    std::vector<float> download(GradientBuffers& grad);
    /// The boundary terms alone at theta (the delta of iteration t, or of the nearest measured
    /// one) with the secondary term's reuse `reuse`, which they advance.
    std::vector<float> boundary_pass(const Buffer<float>& theta, std::uint32_t seed, int spp, int t,
                                     SecondaryReservoirs& reuse);
    void record_trajectory(const KernelLibrary& lib);
    void record_motion();

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

} // namespace tandem::restir_bench
