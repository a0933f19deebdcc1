// The scheduler's plan for the primal images of an optimization iteration: one plain render, or
// the recursive control variate's two parameter states fused into one two-state kernel (CV-PS)
// or rendered by two launches with one seed (CV-PSS). "Recursive Control Variates for Inverse
// Rendering" (Nicolet et al. 2023), Sec. 5 and Appendix B.
#pragma once

#include <string>
#include <vector>

#include "core/scene/params.h"

namespace tandem {

/// How the primal images of an iteration are produced:
///   none  plain PRB: one render of theta_n
///   pss   recursive control variate, primary sample space: theta_n and theta_{n-1} rendered by
///         two launches with the same seed
///   ps    recursive control variate, path space: one fused two-state launch (CV-PS)
enum class CvMode { none, pss, ps };

/// "none", "pss" or "ps"; throws Error otherwise.
CvMode cv_mode(const std::string& name);
const char* cv_mode_name(CvMode mode);

/// The fusion decision: the two primal renders of an iteration (theta_n and theta_{n-1}, same
/// seed) fuse into the two-state kernel when every changing parameter leaves geometry and
/// sampling valid for both states, else they run as two launches (CV-PSS). Every parameter kind
/// today (reflectance, texels, specular, roughness, radiance, and a medium's extinction, albedo,
/// scale and g) changes only how a path is weighted, never the geometry it meets: light sampling
/// uses a fixed table, BSDF and phase samples are re-weighted by the two-state path, and free
/// flights are drawn under a majorant of both states (kernels/path/volume.h). `reason` says why,
/// for the log.
CvMode plan_cv(CvMode requested, const std::vector<const Parameter*>& changing,
               std::string* reason);

} // namespace tandem
