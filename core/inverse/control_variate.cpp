// Host side of the recursive control variate.
#include "core/inverse/control_variate.h"

#include <cmath>

#include "runtime/error.h"

namespace tandem {

CvVariance cv_variance(const std::string& name) {
    if (name == "consistent") return CvVariance::consistent;
    if (name == "reference") return CvVariance::reference;
    throw Error("unknown cv_variance '" + name + "' (expected \"consistent\" or \"reference\")");
}

const char* cv_variance_name(CvVariance v) {
    return v == CvVariance::reference ? "reference" : "consistent";
}

gpu::CvConfig make_cv_config(unsigned iteration, CvVariance variance, unsigned warmup, float beta1,
                             float beta2) {
    gpu::CvConfig c{};
    const unsigned m = iteration > 0 ? iteration - 1 : 0;
    c.beta1 = beta1;
    c.beta2 = beta2;
    c.variance = static_cast<unsigned>(variance);
    c.corr1_after = static_cast<float>(1.0 - std::pow(double(beta1), double(m + 1)));
    c.corr2 = m == 0 ? 1.0f : static_cast<float>(1.0 - std::pow(double(beta2), double(m)));
    c.iteration = iteration;
    c.warmup = warmup;
    c.updates = m;
    return c;
}

} // namespace tandem
