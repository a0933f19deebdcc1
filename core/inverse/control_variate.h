// Host side of the recursive control variate (kernels/shared/cv.h): the per-iteration constants.
#pragma once

#include <string>

#include "shared/cv.h"

namespace tandem {

/// How the control weight's Var[C_{n-1}] is estimated (kernels/shared/cv.h): "consistent" (the
/// default) or "reference" (the paper's eq. 10, to reproduce its behaviour).
enum class CvVariance : unsigned {
    reference = CV_VARIANCE_REFERENCE,
    consistent = CV_VARIANCE_CONSISTENT,
};

/// "reference" or "consistent"; anything else throws Error naming the accepted values.
CvVariance cv_variance(const std::string& name);
const char* cv_variance_name(CvVariance v);

/// The constants of iteration n (0-based) with `warmup` plain iterations (docs/method.md: default
/// 1) and decay rates beta1 (means) and beta2 (second moments): the statistics have been updated m
/// = max(n - 1, 0) times before iteration n, and the bias corrections are computed in double.
gpu::CvConfig make_cv_config(unsigned iteration, CvVariance variance = CvVariance::consistent,
                             unsigned warmup = 1, float beta1 = 0.9f, float beta2 = 0.999f);

} // namespace tandem
