// Host side of the recursive control variate (kernels/shared/cv.h): the per-iteration constants.
#pragma once

#include "shared/cv.h"

namespace tandem {

/// The constants of iteration n (0-based) with `warmup` plain iterations (docs/method.md: default
/// 1) and decay rates beta1 (means) and beta2 (second moments): the statistics have been updated m
/// = max(n - 1, 0) times before iteration n, and the bias corrections are computed in double.
gpu::CvConfig make_cv_config(unsigned iteration, unsigned warmup = 1, float beta1 = 0.9f,
                             float beta2 = 0.999f);

} // namespace tandem
