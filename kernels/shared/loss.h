// Image losses for inverse rendering, per element: the value and its derivative with respect to
// the rendered value, shared by the device kernel (kernels/loss.cl) and the host reference.
// The loss of an image is the mean over all pixel channels, so d = dloss/dx carries 1/N.
#ifndef TANDEM_SHARED_LOSS_H
#define TANDEM_SHARED_LOSS_H

#include "shared/compat.h"

TANDEM_NAMESPACE_BEGIN

#define LOSS_MEAN 0u ///< mean(x): needs no reference
#define LOSS_L1 1u   ///< mean(|x - r|)
#define LOSS_L2 2u   ///< mean((x - r)^2)
#define LOSS_RL2 3u  ///< mean((x - r)^2 / (r^2 + LOSS_RL2_EPS)), relative L2
#define LOSS_RL2_EPS 1e-2f

/// Loss term of one element x against reference r; writes dloss/dx (times inv_n) to *d.
TANDEM_INLINE float loss_element(uint kind, float x, float r, float inv_n, float* d) {
    const float e = x - r;
    if (kind == LOSS_L1) {
        *d = (e > 0.0f ? inv_n : (e < 0.0f ? -inv_n : 0.0f));
        return fabs(e);
    }
    if (kind == LOSS_L2) {
        *d = 2.0f * e * inv_n;
        return e * e;
    }
    if (kind == LOSS_RL2) {
        const float s = 1.0f / (r * r + LOSS_RL2_EPS);
        *d = 2.0f * e * s * inv_n;
        return e * e * s;
    }
    *d = inv_n; // LOSS_MEAN
    return x;
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_LOSS_H
