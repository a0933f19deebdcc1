// PoCL compiles kernels with the LLVM library loaded in this process. Two of its settings decide
// whether a kernel is vectorised across work items, and how: its work-group method, chosen here
// per device, and LLVM's SLP vectoriser, changed here for the kernels that need it off.
#pragma once

#include <string>

#include "runtime/device.h"
#include "runtime/tuning.h"

namespace tandem {

/// Whether `device` is PoCL's (its platform name).
bool is_pocl(const DeviceInfo& device);

/// Whether PoCL's loop vectoriser widens a loop over work items whose body gathers from global
/// memory (a texel, a triangle's vertices, a material by index) on `device`: PoCL's CPU device
/// compiling for an AVX-512 target. PoCL names its CPU device after the LLVM CPU it compiles for
/// ("pthread-skylake-avx512", "cpu-znver4-..."), which is what matters, not the host's CPU (PoCL
/// 3.1's LLVM 15 knows Zen 4 only as `znver3`; POCL_CPU_TARGET may choose another). LLVM's x86
/// cost model treats a gather as legal only with AVX-512, or with AVX2 on cores it marks as
/// having fast gathers; elsewhere (`haswell`, which PoCL 3.1 also picks for AMD Zen 3, and the
/// `znver` targets before Zen 4) it scalarises every gather and finds the widened loop not
/// beneficial, so the wavefront's shading stages stay one path per instruction
/// (POCL_VECTORIZER_REMARKS=1: "the cost-model indicates that vectorization is not
/// beneficial"). AVX2 cores with fast gathers (Intel's `skylake` clients and later) answer false
/// here: not measured. Other platforms (GPUs, other CPU runtimes, which vectorise by their own
/// rules) answer false.
bool pocl_widens_gathers(const DeviceInfo& device);

/// The work-group method PoCL should compile kernels with on `device`, given the value of
/// POCL_WORK_GROUP_METHOD the user set (`user`, null when unset: Tuning::pocl_work_group_method),
/// or null for PoCL's own choice. A value the user set is theirs. Otherwise, on PoCL's CPU device
/// where the loop vectoriser does not widen gathers (!pocl_widens_gathers: there the renderer and
/// the gradient run as megakernels, one path per work item, which nothing vectorises across work
/// items), "workitemloops": PoCL 3.1's default, "loopvec", runs LLVM's loop and SLP vectorisers
/// over every kernel, and "workitemloops" runs neither, which the megakernels run faster
/// without. The same bits either way (neither vectoriser reassociates without fast-math). Where
/// the loop vectoriser widens gathers (AVX-512), the wavefront needs it: null.
const char* pocl_work_group_method(const DeviceInfo& device, const char* user);

/// The work-group method PoCL compiles kernels with on `device` once a context exists on it, and
/// who chose it: {the user's POCL_WORK_GROUP_METHOD, "POCL_WORK_GROUP_METHOD"}, {Tandem's choice,
/// "Tandem"} or {"loopvec", "PoCL's default"}; empty strings for a device PoCL does not run
/// (`tandem devices` and the Python module's devices() report it).
struct WorkGroupMethod {
    std::string method;
    std::string by;
};
WorkGroupMethod pocl_work_group_method_in_effect(const DeviceInfo& device, const Tuning& tuning);

/// Sets the environment variable POCL_WORK_GROUP_METHOD, which PoCL reads, to
/// pocl_work_group_method(device, the user's) where that names a method and the variable is
/// unset. PoCL reads it when it first compiles a kernel in the process (its LLVM options are set
/// once), so this runs before any program is built (Context's constructor); a later device of the
/// process keeps the first one's choice.
void pocl_choose_work_group_method(const DeviceInfo& device, const Tuning& tuning);

/// The work-group method PoCL compiles this process's kernels with on `device`, as far as Tandem
/// knows: the user's (tuning), else the one pocl_choose_work_group_method set, else empty (PoCL's
/// default). Program cache keys name it (base_build_options).
std::string pocl_work_group_method_for_builds(const DeviceInfo& device, const Tuning& tuning);

/// While one lives, LLVM's SLP vectoriser is off for what PoCL compiles in this process. PoCL
/// compiles a kernel's work-group function at its first launch, so a scope around that launch
/// (and a finish) decides how the kernel is built; kernels first launched elsewhere keep SLP.
///
/// Why: PoCL 3.1 runs the SLP vectoriser over a kernel before the loop vectoriser widens the
/// loop over work items. SLP packs pairs of like scalar operations (two hashes of the RNG, the
/// two fabs of `fabs(x) > fabs(y)`, a struct copy) into <2 x i32> or <4 x i32>, and the loop
/// vectoriser then refuses the whole loop ("instruction return type cannot be vectorized"). A
/// kernel written in scalars for SIMD across work items (kernels/wavefront.cl, wf_shade) then
/// stays scalar; with SLP off it runs 8 paths per instruction (scripts/vectorize_probe.py shows
/// it). The single-ray kernels are faster with SLP (it packs
/// their per-axis arithmetic), hence a scope and not a global switch. SLP changes no
/// floating-point result (it never reassociates without fast-math): the bits are the same.
///
/// How: LLVM's C API LLVMParseCommandLineOptions sets its `-slp-threshold` option (the gain SLP
/// must exceed; 0 by default) out of reach and back to 0, in the libLLVM that PoCL loaded (found
/// among the loaded objects, never loaded here), for LLVM 15 to 19, where the option exists and may
/// be given more than once. Nothing happens on other platforms, where PoCL's LLVM is not found, or
/// with Tuning::pocl_slp (TANDEM_POCL_SLP=1: kept on, to measure what this buys).
class PoclSlpOff {
public:
    PoclSlpOff(const DeviceInfo& device, const Tuning& tuning);
    ~PoclSlpOff();
    PoclSlpOff(const PoclSlpOff&) = delete;
    PoclSlpOff& operator=(const PoclSlpOff&) = delete;
    bool active() const { return m_active; }

private:
    bool m_active = false;
};

} // namespace tandem
