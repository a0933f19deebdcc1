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
// from exponentially weighted Welford statistics of h and d = f - h over earlier iterations
// (Appendix A), and Var[C_{n-1}] from eq. 10, in one of two forms (CvConfig::variance):
//
// - CV_VARIANCE_REFERENCE, the paper's: Var[C_n] = alpha_n^2 (Var[C_{n-1}] + v_h) + v_f
//   - 2 alpha_n c (eq. 10), carried in absolute units from one iteration to the next, each step
//   with the moments of its time. Every sample is then weighted by the inverse of a variance
//   estimated from the few samples before it; on a static scene this keeps about half of the
//   samples (and a 0/0 weight, alpha = 0, where all samples so far were equal).
// - CV_VARIANCE_CONSISTENT, the default: eq. 10 evaluated with one set of moments, the current
//   ones, for the whole history (the stationarity that the moving averages already assume).
//   Unrolled, Var[C_{n-1}] = A v_h + B v_f - 2 D c with A <- alpha^2 (A + 1), B <- alpha^2 B + 1,
//   D <- alpha^2 D + alpha; it equals eq. 10 exactly when the moments are constant. On a static
//   scene (h = f) it gives alpha_n = 1 / (1 + Var[C_{n-1}] / v) and so C_n = the running mean of
//   all samples since the warm-up (Sec. 3.2's alpha = n / (n + 1)), whatever the moments are.
//
// float32 without cancellation. A + B - 2D is a small difference of large numbers (it is ~1/n
// while A, B, D grow like n), so the state keeps E = A + B - 2D itself, E <- alpha^2 E +
// (1 - alpha)^2, and the variance is assembled as
//     Var[C_{n-1}] = E v_f + A (v_h - v_f) + 2 D (v_f - c),
// where v_h - v_f = -(2 c_hd + v_d) and v_f - c = c_hd + v_d come directly from the moments of
// h and d (not as differences of the moments of h and f, which cancel in the same way). A static
// pixel has d = 0 exactly, so v_d = c_hd = 0, Var = E v_f and E = 1/n to rounding: it keeps
// gaining past 10^4 iterations (tested). The reference form uses the same arrangement,
//     Var[C_n] = alpha^2 Var[C_{n-1}] + (1 - alpha)^2 v_f
//                + alpha^2 (v_h - v_f) + 2 alpha (v_f - c).
//
// The 0/0 case. When every moment is zero (all samples so far equal, usually all zero) the
// consistent form takes the limit v_h / v_f = c / v_f = 1, the static scene's, which gives alpha =
// 1 / (1 + E): the running mean. The reference form gives alpha = 0 there, as the paper's code
// does, and so restarts the estimate from the first differing sample: a start-up bias.
//
// The statistics are updated after C_n is formed, so alpha_n never depends on this iteration's
// noise (Fig. 4).
#ifndef TANDEM_SHARED_CV_H
#define TANDEM_SHARED_CV_H

#include "shared/compat.h"

TANDEM_NAMESPACE_BEGIN

/// CvConfig::variance: how Var[C_{n-1}] in eq. 8 is estimated (see the file comment).
#define CV_VARIANCE_REFERENCE 0u
#define CV_VARIANCE_CONSISTENT 1u

/// The state of one element, 40 bytes: the CV estimate, its control weight, the variance
/// recursion and the Welford moments of h and d = f - h.
typedef struct CvState {
    float estimate; ///< C_n: the control-variate estimate of the last iteration
    float alpha;    ///< alpha_n of the last iteration (0 before any)
    float var_cv;   ///< reference: Var[C_{n-1}] by eq. 10 (computed at iteration n with the
                    ///< previous alpha); consistent: E, the coefficient of v_f
    float coef_h;   ///< consistent only: A, the coefficient of (v_h - v_f)
    float coef_c;   ///< consistent only: D, the coefficient of 2 (v_f - c)
    float mean_h;   ///< EW means, stored bias-corrected (see cv_welford_update)
    float mean_d;
    float var_h; ///< EW second moments of h, d and (h, d) (not yet bias-corrected)
    float var_d;
    float cov_hd;
} CvState;
TANDEM_STATIC_ASSERT_SIZE(CvState, 40);

/// Per-iteration constants, computed on the host in double precision (no pow on the device).
/// m = the number of statistics updates done before this iteration.
typedef struct CvConfig {
    float beta1;       ///< decay of the means (0.9)
    float beta2;       ///< decay of the second moments (0.999)
    uint variance;     ///< CV_VARIANCE_REFERENCE or CV_VARIANCE_CONSISTENT
    float corr1_after; ///< 1 - beta1^(m+1): bias correction of the means after the update
    float corr2;       ///< 1 - beta2^m: bias correction of the second moments read by cv_step
    uint iteration;    ///< n (0-based)
    uint warmup;  ///< iterations n <= warmup use C_n = f (the statistics still update from n = 1)
    uint updates; ///< m
} CvConfig;
TANDEM_STATIC_ASSERT_SIZE(CvConfig, 32);

/// A zero state (iteration 0 overwrites the estimate).
TANDEM_INLINE CvState cv_state_zero(void) {
    CvState s;
    s.estimate = 0.0f;
    s.alpha = 0.0f;
    s.var_cv = 0.0f;
    s.coef_h = 0.0f;
    s.coef_c = 0.0f;
    s.mean_h = 0.0f;
    s.mean_d = 0.0f;
    s.var_h = 0.0f;
    s.var_d = 0.0f;
    s.cov_hd = 0.0f;
    return s;
}

/// Appendix A, Listing 2 (two decay rates, start-up bias correction of the means), for the pair
/// (x, y) = (h, d): updates means, variances and covariance in place.
///
/// The means are stored already bias-corrected, M^ = M / (1 - beta1^m), and updated in Welford's
/// form M^ += w (x - M^) with w = (1 - beta1) / (1 - beta1^(m+1)); this equals Listing 2 in exact
/// arithmetic (M^_m = M^_(m-1) + w (x - M^_(m-1)) follows from M_m = beta1 M_(m-1) +
/// (1 - beta1) x). Unlike dividing the raw EW mean by 1 - beta1^m, it is exact where the statistics
/// must be zero: w = 1 on the first update makes M^ = x exactly, and a constant sequence keeps M^ =
/// x, so dx1 dx2 is exactly 0 there instead of +-ulp^2 noise (which the paper's code turns into an
/// arbitrary alpha at iteration 2). Also dx2 = (1 - w) dx1 keeps the sign of dx1, so var_h and
/// var_d are never negative. The moments of (h, f) follow by bilinearity (exactly, in exact
/// arithmetic): v_f = v_h + 2 c_hd + v_d and Cov[h, f] = v_h + c_hd.
TANDEM_INLINE void cv_welford_update(CvState* s, float x, float y, const CvConfig* c) {
    const int first = c->updates == 0u; // w = 1: the means become the sample itself
    // deviations from the bias-corrected means before the update (the sample itself when m = 0)
    const float dx1 = first ? x : x - s->mean_h;
    const float dy1 = first ? y : y - s->mean_d;
    const float w = (1.0f - c->beta1) / c->corr1_after;
    s->mean_h = first ? x : s->mean_h + w * dx1;
    s->mean_d = first ? y : s->mean_d + w * dy1;
    const float dx2 = x - s->mean_h; // deviations from the bias-corrected means after it
    const float dy2 = y - s->mean_d;
    s->var_h = c->beta2 * s->var_h + (1.0f - c->beta2) * (dx1 * dx2);
    s->var_d = c->beta2 * s->var_d + (1.0f - c->beta2) * (dy1 * dy2);
    s->cov_hd = c->beta2 * s->cov_hd + (1.0f - c->beta2) * (dx1 * dy2);
}

/// alpha from eq. 8: NaN or Inf -> 0, then clamped to [0, 1].
TANDEM_INLINE float cv_alpha(float cov, float var_h, float var_cv) {
    const float a = cov / (var_h + var_cv);
    return isfinite(a) ? fmin(fmax(a, 0.0f), 1.0f) : 0.0f;
}

/// The moments of (h, f) that eq. 8 and 10 read, bias-corrected with 1 / corr2, from those of
/// (h, d = f - h): v_f and c, and the two differences that the variance recursion needs without
/// cancellation, v_h - v_f = -(2 c_hd + v_d) and v_f - c = c_hd + v_d.
typedef struct CvMoments {
    float v_h, v_f, cov, h_minus_f, f_minus_c;
    int zero; ///< every moment is exactly zero (all samples so far equal)
} CvMoments;

TANDEM_INLINE CvMoments cv_moments(const CvState* s, const CvConfig* c) {
    const float inv = 1.0f / c->corr2; // bias-corrected moments
    const float v_h = s->var_h * inv, v_d = s->var_d * inv, c_hd = s->cov_hd * inv;
    CvMoments m;
    m.v_h = v_h;
    m.v_f = v_h + (2.0f * c_hd + v_d);
    m.cov = v_h + c_hd;
    m.h_minus_f = -(2.0f * c_hd + v_d);
    m.f_minus_c = c_hd + v_d;
    m.zero = v_h == 0.0f && v_d == 0.0f && c_hd == 0.0f;
    return m;
}

/// Var[C] of the consistent form from its coefficients E, A, D and moments m: E v_f +
/// A (v_h - v_f) + 2 D (v_f - c); NaN or Inf -> 0, and >= 0.
TANDEM_INLINE float cv_consistent_variance(float E, float A, float D, const CvMoments* m) {
    const float v = E * m->v_f + A * m->h_minus_f + 2.0f * D * m->f_minus_c;
    return isfinite(v) ? fmax(v, 0.0f) : 0.0f;
}

/// One step of eq. 10 in the reference form, arranged without cancellation: Var[C] after a step
/// with weight a from V = the variance before it, a^2 V + (1 - a)^2 v_f + a^2 (v_h - v_f) +
/// 2 a (v_f - c); NaN or Inf -> 0, and >= 0.
TANDEM_INLINE float cv_reference_variance(float V, float a, const CvMoments* m) {
    const float b = 1.0f - a, a2 = a * a;
    const float v = a2 * V + b * b * m->v_f + a2 * m->h_minus_f + 2.0f * a * m->f_minus_c;
    return isfinite(v) ? fmax(v, 0.0f) : 0.0f;
}

/// Var[C_n], the variance of the estimate in `s` after iteration n, in absolute units, for images
/// and metrics: with c = the constants of iteration n + 1 (the moments then include iteration n's
/// update). The consistent form evaluates its coefficients with those moments; the reference form
/// takes one more step of eq. 10 from its stored Var[C_{n-1}] with alpha_n (what iteration n + 1
/// would compute first).
TANDEM_INLINE float cv_estimate_variance(const CvState* s, const CvConfig* c) {
    if (c->updates == 0u) return 0.0f;
    const CvMoments m = cv_moments(s, c);
    return c->variance == CV_VARIANCE_CONSISTENT
               ? cv_consistent_variance(s->var_cv, s->coef_h, s->coef_c, &m)
               : cv_reference_variance(s->var_cv, s->alpha, &m);
}

/// C_n = f: iteration 0, the warm-up, and the first iteration without statistics. The consistent
/// recursion restarts from Var[C_n] = v_f (E = 1, A = D = 0), which is eq. 10 with alpha = 0; the
/// reference one from var_cv = 0, as the paper's code (it is multiplied by alpha = 0 next).
TANDEM_INLINE void cv_restart(CvState* s, float f, const CvConfig* c) {
    s->estimate = f;
    s->alpha = 0.0f;
    s->var_cv = c->variance == CV_VARIANCE_CONSISTENT ? 1.0f : 0.0f;
    s->coef_h = 0.0f;
    s->coef_c = 0.0f;
}

/// One iteration for one element (Var[C_{n-1}], eq. 8, eq. 6, then the Welford update, in that
/// order); returns C_n.
TANDEM_INLINE float cv_step(CvState* s, float h, float f, const CvConfig* c) {
    if (c->iteration == 0u) { // C_0 = F_0; old = new, nothing to learn from
        cv_restart(s, f, c);
        return f;
    }
    if (c->iteration > c->warmup && c->updates > 0u) {
        const CvMoments m = cv_moments(s, c); // lagged: before this iteration's update
        if (c->variance == CV_VARIANCE_CONSISTENT) {
            // coefficients are finite and >= 0 by construction; anything else (a corrupted
            // state) restarts the recursion at Var[C] = v_f rather than poisoning it for good
            const int sane = isfinite(s->var_cv) && isfinite(s->coef_h) && isfinite(s->coef_c) &&
                             s->var_cv >= 0.0f && s->coef_h >= 0.0f && s->coef_c >= 0.0f;
            const float E = sane ? s->var_cv : 1.0f, A = sane ? s->coef_h : 0.0f,
                        D = sane ? s->coef_c : 0.0f;
            // the 0/0 limit v_h / v_f = c / v_f = 1, or eq. 8 with Var[C_{n-1}] from the
            // coefficients and the current moments
            const float a = m.zero ? 1.0f / (1.0f + E)
                                   : cv_alpha(m.cov, m.v_h, cv_consistent_variance(E, A, D, &m));
            const float b = 1.0f - a, a2 = a * a;
            s->var_cv = a2 * E + b * b;
            s->coef_h = a2 * (A + 1.0f);
            s->coef_c = a2 * D + a;
            s->alpha = a;
        } else {
            // eq. 10 with the previous alpha: the variance of the previous CV estimate
            s->var_cv = cv_reference_variance(s->var_cv, s->alpha, &m);
            s->alpha = cv_alpha(m.cov, m.v_h, s->var_cv);
        }
        s->estimate = f + s->alpha * (s->estimate - h);
    } else {
        cv_restart(s, f, c);
    }
    cv_welford_update(s, h, f - h, c); // after the CV: a one-iteration lag
    return s->estimate;
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_CV_H
