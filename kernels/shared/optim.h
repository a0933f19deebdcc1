// Optimizer steps on flat parameter buffers (one element at a time), shared by the device kernels
// (kernels/optim.cl) and the host reference: Adam (Kingma and Ba 2015, with bias correction) and
// plain gradient descent, each clamped to the parameter's valid range.
#ifndef TANDEM_SHARED_OPTIM_H
#define TANDEM_SHARED_OPTIM_H

#include "shared/compat.h"

TANDEM_NAMESPACE_BEGIN

/// Adam hyper-parameters of one step, 32 bytes. The bias corrections 1 - beta^t are computed on
/// the host (in double), so no implementation-defined pow() enters the update.
typedef struct AdamConfig {
    float beta1;
    float beta2;
    float epsilon;
    float correction1; ///< 1 - beta1^t, t = 1 for the first step
    float correction2; ///< 1 - beta2^t
    uint pad0;
    uint pad1;
    uint pad2;
} AdamConfig;
TANDEM_STATIC_ASSERT_SIZE(AdamConfig, 32);

/// One Adam step of parameter p with gradient g and learning rate lr; m and v are the first and
/// second moment estimates. Returns the new p, clamped to [lo, hi]. A parameter with lr = 0 is
/// not being optimized: it and its moments stay exactly as they are (no clamping either).
TANDEM_INLINE float adam_step(float p, float g, float lr, float lo, float hi, AdamConfig c,
                              float* m, float* v) {
    if (lr == 0.0f) return p;
    *m = c.beta1 * *m + (1.0f - c.beta1) * g;
    *v = c.beta2 * *v + (1.0f - c.beta2) * g * g;
    const float m_hat = *m / c.correction1;
    const float v_hat = *v / c.correction2;
    const float q = p - lr * m_hat / (sqrt(v_hat) + c.epsilon);
    return fmin(fmax(q, lo), hi);
}

/// One gradient-descent step, clamped to [lo, hi]; lr = 0 leaves p untouched.
TANDEM_INLINE float sgd_step(float p, float g, float lr, float lo, float hi) {
    if (lr == 0.0f) return p;
    return fmin(fmax(p - lr * g, lo), hi);
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_OPTIM_H
