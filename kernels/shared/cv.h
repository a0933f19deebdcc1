// Recursive control variate ("Recursive Control Variates for Inverse Rendering", Nicolet,
// Rousselle, Novák, Keller, Jakob, Müller, SIGGRAPH 2023: Sec. 3.2 and Appendix A; docs/method.md,
// "Recursive control variate"), per image element (pixel channel). Shared by the device image
// kernel (kernels/loss.cl: cv_loss_terms) and the host tests, which run this very code on toy
// sequences.
//
// Each iteration n >= 1 receives h = <F_{n-1}>_n (the previous parameter state rendered with this
// iteration's paths) and f = <F_n>_n (the new state, same paths) and forms
//     C_n = f + alpha_n (C_{n-1} - h)                                   (eq. 6)
// with alpha_n = Cov[f, h] / (Var[h] + Var[C_{n-1}])                    (eq. 8)
// from exponentially weighted Welford statistics of (h, f) over earlier iterations (Appendix A),
// and Var[C_{n-1}] from the recurrence of eq. 10 with the previous alpha. The statistics are
// updated after C_n is formed, so alpha_n never depends on this iteration's noise (Fig. 4).
#ifndef TANDEM_SHARED_CV_H
#define TANDEM_SHARED_CV_H

#include "shared/compat.h"

TANDEM_NAMESPACE_BEGIN

/// The state of one element, 32 bytes: the CV estimate, its control weight and variance, and the
/// Welford moments of h (x) and f (y).
typedef struct CvState {
    float estimate; ///< C_{n}: the control-variate estimate of the last iteration
    float alpha;    ///< alpha_n of the last iteration (0 before any)
    float var_cv;   ///< Var[C_n] by eq. 10
    float mean_h;   ///< EW means, stored bias-corrected (see cv_welford_update)
    float mean_f;
    float var_h;    ///< EW second moments (not yet bias-corrected)
    float var_f;
    float cov;
} CvState;
TANDEM_STATIC_ASSERT_SIZE(CvState, 32);

/// Per-iteration constants, computed on the host in double precision (no pow on the device).
/// m = the number of statistics updates done before this iteration.
typedef struct CvConfig {
    float beta1;        ///< decay of the means (0.9)
    float beta2;        ///< decay of the second moments (0.999)
    float corr1_before; ///< 1 - beta1^m (1 if m = 0); informational: the update below keeps the
                        ///< means bias-corrected and needs only corr1_after
    float corr1_after;  ///< 1 - beta1^(m+1): bias correction of the means after the update
    float corr2;        ///< 1 - beta2^m: bias correction of the second moments read by cv_step
    uint iteration;     ///< n (0-based)
    uint warmup;        ///< iterations n <= warmup use C_n = f (the statistics still update from n = 1)
    uint updates;       ///< m
} CvConfig;
TANDEM_STATIC_ASSERT_SIZE(CvConfig, 32);

/// A zero state (iteration 0 overwrites the estimate).
TANDEM_INLINE CvState cv_state_zero(void) {
    CvState s;
    s.estimate = 0.0f;
    s.alpha = 0.0f;
    s.var_cv = 0.0f;
    s.mean_h = 0.0f;
    s.mean_f = 0.0f;
    s.var_h = 0.0f;
    s.var_f = 0.0f;
    s.cov = 0.0f;
    return s;
}

/// Appendix A, Listing 2 (two decay rates, start-up bias correction of the means), for the pair
/// (x, y) = (h, f): updates means, variances and covariance in place.
///
/// The means are stored already bias-corrected, M^ = M / (1 - beta1^m), and updated in Welford's
/// form M^ += w (x - M^) with w = (1 - beta1) / (1 - beta1^(m+1)); this equals Listing 2 in exact
/// arithmetic (M^_m = M^_(m-1) + w (x - M^_(m-1)) follows from M_m = beta1 M_(m-1) + (1 - beta1) x).
/// Unlike dividing the raw EW mean by 1 - beta1^m, it is exact where the statistics must be zero:
/// w = 1 on the first update makes M^ = x exactly, and a constant sequence keeps M^ = x, so
/// dx1 dx2 is exactly 0 there instead of +-ulp^2 noise. (A negative one-sample "variance" made
/// var_cv clamp to 0 and alpha = cov / var_h = 1 at iteration 2, and with h == f the pair
/// alpha = 1, var_cv = 0 is a fixed point of eq. 10: the estimate froze at C_1 for good.)
/// Also dx2 = (1 - w) dx1 keeps the sign of dx1, so var_h and var_f are never negative.
TANDEM_INLINE void cv_welford_update(CvState* s, float x, float y, const CvConfig* c) {
    const int first = c->updates == 0u; // w = 1: the means become the sample itself
    // deviations from the bias-corrected means before the update (the sample itself when m = 0)
    const float dx1 = first ? x : x - s->mean_h;
    const float dy1 = first ? y : y - s->mean_f;
    const float w = (1.0f - c->beta1) / c->corr1_after;
    s->mean_h = first ? x : s->mean_h + w * dx1;
    s->mean_f = first ? y : s->mean_f + w * dy1;
    const float dx2 = x - s->mean_h; // deviations from the bias-corrected means after it
    const float dy2 = y - s->mean_f;
    s->var_h = c->beta2 * s->var_h + (1.0f - c->beta2) * (dx1 * dx2);
    s->var_f = c->beta2 * s->var_f + (1.0f - c->beta2) * (dy1 * dy2);
    s->cov = c->beta2 * s->cov + (1.0f - c->beta2) * (dx1 * dy2);
}

/// alpha from eq. 8: NaN or Inf -> 0, then clamped to [0, 1].
TANDEM_INLINE float cv_alpha(float cov, float var_h, float var_cv) {
    const float a = cov / (var_h + var_cv);
    return isfinite(a) ? fmin(fmax(a, 0.0f), 1.0f) : 0.0f;
}

/// One iteration for one element (eq. 10, eq. 8, eq. 6, then the Welford update, in that order);
/// returns C_n.
TANDEM_INLINE float cv_step(CvState* s, float h, float f, const CvConfig* c) {
    if (c->iteration == 0u) { // C_0 = F_0; old = new, nothing to learn from
        s->estimate = f;
        return f;
    }
    if (c->iteration > c->warmup && c->updates > 0u) {
        const float inv = 1.0f / c->corr2; // bias-corrected, lagged moments
        const float v_h = s->var_h * inv, v_f = s->var_f * inv, cov = s->cov * inv;
        const float a_prev = s->alpha;
        // eq. 10 with the previous alpha: the variance of the previous CV estimate
        const float v_cv = a_prev * a_prev * (s->var_cv + v_h) + v_f - 2.0f * a_prev * cov;
        s->var_cv = isfinite(v_cv) ? fmax(v_cv, 0.0f) : 0.0f;
        s->alpha = cv_alpha(cov, v_h, s->var_cv);
        s->estimate = f + s->alpha * (s->estimate - h);
    } else {
        s->estimate = f;
    }
    cv_welford_update(s, h, f, c); // after the CV: a one-iteration lag
    return s->estimate;
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_CV_H
