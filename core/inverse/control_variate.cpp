// Host side of the recursive control variate.
#include "core/inverse/control_variate.h"

#include <cmath>

namespace tandem {

gpu::CvConfig make_cv_config(unsigned iteration, unsigned warmup, float beta1, float beta2) {
    gpu::CvConfig c{};
    const unsigned m = iteration > 0 ? iteration - 1 : 0;
    c.beta1 = beta1;
    c.beta2 = beta2;
    c.corr1_before = m == 0 ? 1.0f : static_cast<float>(1.0 - std::pow(double(beta1), double(m)));
    c.corr1_after = static_cast<float>(1.0 - std::pow(double(beta1), double(m + 1)));
    c.corr2 = m == 0 ? 1.0f : static_cast<float>(1.0 - std::pow(double(beta2), double(m)));
    c.iteration = iteration;
    c.warmup = warmup;
    c.updates = m;
    return c;
}

} // namespace tandem
