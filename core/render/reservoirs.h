// Light-sample reservoirs as the passes read them (ReSTIR: docs/restir.md, kernels/path/restir.h,
// kernels/path/resample.h): what a chain of reservoirs does (RestirConfig), whether a scene can
// use them, and ReservoirPasses, which fills the PathReservoirs and PathResample records the
// passes take (core/render/passes.h). Who keeps the reservoirs from one iteration to the next is
// the inverse layer's business (core/inverse/restir.h); what a pass reads is decided here.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/render/device_scene.h"
#include "core/render/gradient_buffers.h"
#include "core/render/passes.h"
#include "shared/reservoir.h"

namespace tandem {

/// Which share of the primary vertex's direct light the reservoirs estimate (docs/restir.md, "The
/// reservoir's share of direct light"). The values are the kernels' RESTIR_DIRECT_*.
enum class RestirDirect {
    mis = 0,      ///< NEE's MIS share; BSDF sampling keeps the rest, as in plain PRB
    all = 1,      ///< all of it wherever NEE can sample the light
    automatic = 2 ///< all at a diffuse vertex, the MIS share elsewhere
};

/// "mis", "all" or "auto"; restir_direct() reads them back and throws on anything else.
const char* restir_direct_name(RestirDirect d);
RestirDirect restir_direct(const std::string& name);

/// What ReSTIR light-sample reuse does: the "restir" object of a `tandem optimize` config and the
/// options of `tandem grad --restir`.
struct RestirConfig {
    bool adjoint = true; ///< reuse light samples at the adjoint's primary vertex
    /// and, in a chain of its own, at the primal image's ("cv": "none" only; docs/restir.md)
    bool primal = false;
    int candidates = 16;     ///< fresh light samples per slot and iteration (streaming RIS)
    bool temporal = true;    ///< combine with the slot's own reservoir of the previous iteration
    int spatial = 2;         ///< and with this many reservoirs of nearby slots (0 to 7)
    float m_cap = 20.0f;     ///< a previous reservoir's confidence is capped at this when read
    int burn_in = 8;         ///< resampling-only passes at the initial parameters
    bool visibility = true;  ///< targets include visibility (two shadow rays per neighbour)
    float normal_cos = 0.9f; ///< neighbours: normals within this cosine of the slot's
    float depth_rel = 0.1f;  ///< neighbours: camera distance within this fraction
    /// the share of direct light reservoirs take: all of it at diffuse vertices (docs/restir.md)
    RestirDirect direct = RestirDirect::automatic;
};

/// Checks `config` (ranges of every field); throws Error "WHERE: ..." naming the field.
void validate_restir_config(const RestirConfig& config, const std::string& where);

/// What ReSTIR can do for `scene`: an empty string if it can serve it, else why not (no light to
/// sample, or max_depth < 2 so no path samples a light at its primary vertex).
std::string restir_unsupported(const RenderScene& scene);

/// The build flags of a device scene whose passes read reservoirs: `features` with RESTIR=1.
BuildFlags restir_features(BuildFlags features);

/// The records the passes take for one chain of reservoirs of a view of a scene (built with
/// RESTIR=1), `spp` slots per pixel of its film, resampled as `config` says.
class ReservoirPasses {
public:
    /// Throws Error for a config out of range, a scene built without RESTIR=1 or one it cannot
    /// serve (restir_unsupported), or more than 2^32 slots.
    ReservoirPasses(const View& view, const RestirConfig& config, int spp);

    const RestirConfig& config() const { return m_config; }
    int spp() const { return m_spp; }
    std::size_t slots() const { return m_slots; }

    /// What a pass reads: the reservoirs `current` and how.
    PathReservoirs read(const Buffer<gpu::Reservoir>& current) const;
    /// read(current) to be resampled first from `prev` (their domain `params_old`) with the
    /// pass's seed `seed`, for the elements `grad` differentiates.
    PathReservoirs resampled(const Buffer<gpu::Reservoir>& current, const Buffer<float>& params_old,
                             const Buffer<gpu::Reservoir>& prev, const GradientBuffers& grad,
                             std::uint32_t seed) const;

private:
    RestirConfig m_config;
    int m_spp;
    std::size_t m_slots;
    unsigned m_radius;      ///< RestirParams::radius
    float m_radiance_floor; ///< RestirParams::radiance_floor, fixed for the run
    /// First elements of the lights' radiance parameters (environment, area emitters), distinct
    std::vector<unsigned> m_light_params;
};

} // namespace tandem
