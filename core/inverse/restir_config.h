// What ReSTIR light-sample reuse in the adjoint does (core/inverse/restir.h; docs/restir.md): the
// "restir" object of a `tandem optimize` config and the options of `tandem grad --restir`.
#pragma once

#include <string>

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

struct RestirConfig {
    bool adjoint = true;     ///< reuse light samples at the adjoint's primary vertex
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

} // namespace tandem
