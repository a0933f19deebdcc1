// The scheduler's plan for the primal images of an iteration.
#include "core/render/schedule.h"

#include "runtime/error.h"

namespace tandem {

CvMode cv_mode(const std::string& name) {
    if (name == "none") return CvMode::none;
    if (name == "pss") return CvMode::pss;
    if (name == "ps") return CvMode::ps;
    throw Error("unknown control variate '" + name + "' (none, pss, ps)");
}

const char* cv_mode_name(CvMode mode) {
    return mode == CvMode::none ? "none" : mode == CvMode::pss ? "pss" : "ps";
}

CvMode plan_cv(CvMode requested, const std::vector<const Parameter*>& changing,
               std::string* reason) {
    if (requested == CvMode::none) {
        *reason = "plain PRB, no control variate";
        return CvMode::none;
    }
    if (requested == CvMode::pss) {
        *reason = "CV-PSS as requested: two launches (theta_n, theta_{n-1}) with the same seed";
        return CvMode::pss;
    }
    // Parameters that move geometry would invalidate the shared path vertices (a shift mapping
    // would be needed, Nicolet et al. 2023, Sec. 6): two launches with one seed instead.
    for (const Parameter* p : changing)
        if (p->moves_geometry()) {
            *reason = "CV-PSS: " + p->name + " moves geometry, which two-state paths cannot share";
            return CvMode::pss;
        }
    std::string names;
    for (const Parameter* p : changing)
        names += (names.empty() ? "" : ", ") + p->name;
    *reason =
        "CV-PS: fused two-state kernel (the changing parameters, " + names + ", move no geometry)";
    return CvMode::ps;
}

} // namespace tandem
