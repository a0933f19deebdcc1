// ReSTIR reservoirs (kernels/shared/reservoir.h) on the host: the defensive pairwise MIS weights
// sum to 1 over the domains that can produce a sample, streaming weighted reservoir sampling picks
// each candidate in proportion to its weight, and a 1-D model of the whole resampling chain built
// on those functions is unbiased (and the test notices a chain that is not); a second model, of
// the secondary boundary's reuse over guided edge points, shows which guide keeps it unbiased.
//
// The method is that of "Amortizing Samples in Physics-Based Inverse Rendering using ReSTIR"
// (Wang, Wyman, Wu, Zhao, SIGGRAPH Asia 2023): every gradient iteration draws a canonical sample by
// resampled importance sampling (RIS), then combines it with the reservoirs the previous iteration
// left at the same pixel (temporal) and at nearby pixels (spatial), whose targets were evaluated
// under the previous parameters. The combine is generalized RIS with defensive pairwise MIS weights
// and confidences M capped at 20.
//
// Tolerances and statistics:
// - Sum to 1: each weight is a few float operations on values in [0, 1], so each is good to a few
//   ulp of 1 (~1e-7); the worst sum over 20,000 random draws with up to 9 terms is well below the
//   1e-6 asked. A neighbour's weight off its own support must be exactly 0 (not merely small).
// - WRS frequencies: n independent streams pick index i with probability p_i = w_i / sum w; the
//   count is binomial, and every index must lie within 4 standard errors sqrt(p (1 - p) / n) of it
//   (a false alarm about once in 16,000 per index; the seeds are fixed, so the test is
//   deterministic). A rule that tests the coin against the sum before adding w is rejected at
//   far more than 10 standard errors: the test has power.
// - The 1-D chain: the bias of h(Y) W at the last iteration is averaged over the pixels of one run
//   (pixels of one run share samples through reuse, so they are not independent) and the per-run
//   means of 8,000 independent runs give a z-score. |z| < 4 for an unbiased configuration (over
//   12 seeds the z-scores of both had mean and spread as N(0, 1) predicts, and 400,000 runs put
//   each bias within 0.0004 of 0, |z| < 1.4, on an integral of 0.49); each deliberate error
//   (a neighbour's support tested without visibility, or empty neighbours dropped) is biased by
//   about a third of the integral, |z| > 100, and must give |z| > 10.
#include <doctest/doctest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>
#include <vector>

#include "shared/reservoir.h"
#include "shared/rng.h"

using namespace tandem;

namespace {

/// A random target value: exactly 0 with probability 1/4, else log-uniform over a narrow range
/// (0.1 to 10, where the ratios are far from 0 and 1) or a wide one (1e-30 to 1e30).
float random_target(gpu::uint seed, gpu::uint trial, gpu::uint dim) {
    const float u = gpu::rng_uniform(seed, trial, 0, dim);
    if (u < 0.25f) return 0.0f;
    const double v = gpu::rng_uniform(seed, trial, 1, dim);
    const double decades = u < 0.625f ? 1.0 : 30.0;
    return float(std::pow(10.0, decades * (2.0 * v - 1.0)));
}

/// Mean and standard error of the mean of a list of values.
struct MeanSe {
    double mean = 0, se = 0;
    double z() const { return mean / se; }
};

MeanSe mean_se(const std::vector<double>& v) {
    double s = 0, s2 = 0;
    for (double x : v)
        s += x;
    const double mean = s / double(v.size());
    for (double x : v)
        s2 += (x - mean) * (x - mean);
    return {mean, std::sqrt(s2 / double(v.size() - 1) / double(v.size()))};
}

// ---- The 1-D model of the resampling chain -------------------------------------------------
//
// Shading points x in [0, 1) (k_pixels = 32 pixels, pixel p jittered over [p, p + 1) / 32 anew
// in each of k_iterations = 6 iterations) see a 1-D light y in [0, 1): a dim part (Le = 1) on
// [0, 0.85] and a bright part (Le = 30) on (0.85, 1). The bright part is occluded from every x
// farther than 0.12 from x = 0.3, and every x is occluded from the light within 0.1 of itself.
// The parameter is an albedo a_t(x) that moves with the iteration t, so neighbours' targets under
// the previous parameters differ from the current ones:
//   unshadowed target  h0_t(x, y) = a_t(x) g(x, y) Le(y),  a_t(x) = 0.5 + 0.4 sin(7x + 0.9t),
//                                   g(x, y) = 1 + 0.8 cos(6 (y - x));
//   integrand = shadowed target  h_t(x, y) = h0_t(x, y) V(x, y).
// Candidates come from p_c(y), proportional to power: 80 % on the bright part, uniform on each.
// Per iteration and pixel:
// 1. Canonical RIS: k_candidates = 4 candidates, weights h0 / p_c, streamed through wrs_update;
//    the pick y_c has W_c = sum w / (4 h0(y_c)), confidence M_c = 1.
// 2. First iteration: the reservoir is (y_c, W_c) if its target P_c = h_t(x, y_c) > 0, else empty.
//    Later iterations combine it with the previous iteration's reservoir at the same pixel and at
//    k_spatial = 2 pixels offset uniformly in [-3, 3] (clamped to the film; repeats allowed), each
//    with M_i capped at RESERVOIR_DEFAULT_M_CAP, using the defensive pairwise weights of
//    reservoir.h with P_ci = h_t(x, y_i), P_ii = h0_{t-1}(x_i, y_i) (unshadowed, as the kernel:
//    W_i > 0 implies y_i visible from x_i), P_ic = h_{t-1}(x_i, y_c)
//    (x_i: neighbour i's shading point). An empty neighbour keeps its confidence in M_sum and
//    offers weight 0 (its canonical term still uses x_i). The resampling weights m P W go through
//    wrs_update (canonical first); the pick Y gets W = sum w / h_t(x, Y), and M = M_sum.
// The estimate at the last iteration is h(x, Y) W, against the exact integral of h over y at the
// same x (closed form below). Variants: "cheap mode" uses h0 as every target (the integrand stays
// h); the deliberate error evaluates the neighbour's own targets P_ii and P_ic without V, so
// neighbour i claims samples it could never have produced (occluded at x_i) and the canonical
// gives them up: the weights no longer sum to 1 where it matters, and the chain loses energy.
// The last variant drops an empty neighbour (a valid shading point whose reservoir holds no
// sample) from the combine, confidence and canonical term included. Whether a reservoir is empty
// depends on its own random samples, so a neighbour that is kept is one whose sample came out
// non-empty: its contribution weight, unbiased over both outcomes, is too large given that one,
// and the chain gains energy. An empty neighbour must stay in M_sum and in the canonical's terms
// with a resampling weight of 0; only tests on shading points (never on samples) may reject one.

constexpr int k_pixels = 32, k_iterations = 6, k_candidates = 4, k_spatial = 2, k_radius = 3;

enum class Variant { shadowed, cheap, unshadowed_support, drop_empty };

double light_le(double y) {
    return y > 0.85 ? 30.0 : 1.0;
}
double light_pdf(double y) {
    return y > 0.85 ? 0.8 / 0.15 : 0.2 / 0.85;
}
double light_sample(double u) {
    return u < 0.8 ? 0.85 + 0.15 * u / 0.8 : 0.85 * (u - 0.8) / 0.2;
}
double visibility(double x, double y) {
    const bool bright_blocked = y > 0.85 && std::fabs(x - 0.3) > 0.12;
    return bright_blocked || std::fabs(y - x) < 0.1 ? 0.0 : 1.0;
}
double albedo(double x, int t) {
    return 0.5 + 0.4 * std::sin(7.0 * x + 0.9 * t);
}
double h0(double x, double y, int t) {
    return albedo(x, t) * (1.0 + 0.8 * std::cos(6.0 * (y - x))) * light_le(y);
}
double h(double x, double y, int t) {
    return h0(x, y, t) * visibility(x, y);
}

/// The integral over y in [a, b] of g(x, y) (0 if the interval is empty).
double g_integral(double x, double a, double b) {
    return b <= a ? 0.0 : (b - a) + 0.8 / 6.0 * (std::sin(6.0 * (b - x)) - std::sin(6.0 * (a - x)));
}
/// The same over [a, b] less the self-occluded (x - 0.1, x + 0.1).
double g_visible(double x, double a, double b) {
    return g_integral(x, a, b) - g_integral(x, std::max(a, x - 0.1), std::min(b, x + 0.1));
}
/// The exact integral over y of h_t(x, y).
double exact_integral(double x, int t) {
    const double bright = std::fabs(x - 0.3) > 0.12 ? 0.0 : 30.0 * g_visible(x, 0.85, 1.0);
    return albedo(x, t) * (g_visible(x, 0.0, 0.85) + bright);
}

/// One run of the chain; returns the mean over pixels of h(x, Y) W - integral at the last
/// iteration. Random numbers: rng_uniform(seed, run, t * k_pixels + pixel, dim).
double run_chain(Variant variant, gpu::uint seed, gpu::uint run) {
    const bool cheap = variant == Variant::cheap;
    // the current target, and the target a neighbour's domain is tested with
    auto target = [&](double x, double y, int t) { return cheap ? h0(x, y, t) : h(x, y, t); };
    auto domain = [&](double x, double y, int t) {
        return variant == Variant::unshadowed_support ? h0(x, y, t) : target(x, y, t);
    };
    std::vector<gpu::Reservoir> prev(k_pixels), cur(k_pixels);
    double bias = 0;
    for (int t = 0; t < k_iterations; ++t) {
        for (int p = 0; p < k_pixels; ++p) {
            gpu::uint dim = 0;
            auto uniform = [&] {
                return gpu::rng_uniform(seed, run, gpu::uint(t * k_pixels + p), dim++);
            };
            const float x = float((p + double(uniform())) / k_pixels);
            // 1. canonical RIS with the unshadowed target
            float w_sum = 0.0f, y_c = 0.0f;
            for (int m = 0; m < k_candidates; ++m) {
                const float y = float(light_sample(uniform()));
                const float w = float(h0(x, y, t) / light_pdf(y));
                if (gpu::wrs_update(&w_sum, w, uniform())) y_c = y;
            }
            const double h0_c = h0(x, y_c, t);
            const float W_c = h0_c > 0 ? float(w_sum / (k_candidates * h0_c)) : 0.0f;
            const float P_c = float(target(x, y_c, t));
            gpu::Reservoir r = gpu::reservoir_empty();
            r.prim = gpu::uint(p);
            r.b1 = x;
            r.M = 1.0f;
            if (t == 0) {
                if (P_c > 0.0f) {
                    r.light = 0;
                    r.u1 = y_c;
                    r.W = W_c;
                }
                cur[p] = r;
                continue;
            }
            // 2. combine with the previous iteration's reservoirs
            int q[1 + k_spatial] = {p};
            for (int s = 1; s <= k_spatial; ++s) {
                const int offset = std::min(int(uniform() * (2 * k_radius + 1)), 2 * k_radius);
                q[s] = std::clamp(p + offset - k_radius, 0, k_pixels - 1);
            }
            const float M_c = 1.0f;
            float M_sum = M_c;
            gpu::uint k = 0;
            const gpu::Reservoir* nb[1 + k_spatial];
            for (int i = 0; i <= k_spatial; ++i) {
                if (variant == Variant::drop_empty && gpu::reservoir_is_empty(&prev[q[i]]))
                    continue;
                nb[k++] = &prev[q[i]];
                M_sum += std::min(prev[q[i]].M, RESERVOIR_DEFAULT_M_CAP);
            }
            float m_c = gpu::pairwise_mis_canonical_start(M_sum, M_c, k);
            float w[1 + k_spatial], y[1 + k_spatial];
            for (gpu::uint i = 0; i < k; ++i) {
                const gpu::Reservoir& n = *nb[i];
                const float M_i = std::min(n.M, RESERVOIR_DEFAULT_M_CAP);
                const float P_ic = float(domain(n.b1, y_c, t - 1));
                m_c += gpu::pairwise_mis_canonical_term(M_i, M_sum, M_c, P_c, P_ic);
                w[i] = 0.0f;
                y[i] = n.u1;
                if (gpu::reservoir_is_empty(&n)) continue;
                const float P_ci = float(target(x, n.u1, t));
                // as the kernel (restir.cl): unshadowed, since W_i > 0 implies its sample was
                // visible from x_i, where the shadowed target equals it
                const float P_ii = float(h0(n.b1, n.u1, t - 1));
                w[i] = gpu::pairwise_mis_neighbour(M_i, M_sum, M_c, P_ii, P_ci) * P_ci * n.W;
            }
            float total = 0.0f, y_pick = 0.0f;
            bool picked = gpu::wrs_update(&total, m_c * P_c * W_c, uniform());
            if (picked) y_pick = y_c;
            for (gpu::uint i = 0; i < k; ++i) {
                if (gpu::wrs_update(&total, w[i], uniform())) {
                    picked = true;
                    y_pick = y[i];
                }
            }
            const float P_y = picked ? float(target(x, y_pick, t)) : 0.0f;
            if (P_y > 0.0f) {
                r.light = 0;
                r.u1 = y_pick;
                r.W = total / P_y;
            }
            r.M = M_sum;
            cur[p] = r;
        }
        std::swap(prev, cur);
    }
    const int last = k_iterations - 1;
    for (const gpu::Reservoir& r : prev) {
        const double est = gpu::reservoir_is_empty(&r) ? 0.0 : h(r.b1, r.u1, last) * r.W;
        bias += est - exact_integral(r.b1, last);
    }
    return bias / k_pixels;
}

/// The bias of the chain over `runs` independent runs, as a mean and its standard error.
MeanSe chain_bias(Variant variant, gpu::uint seed, int runs) {
    std::vector<double> per_run(runs);
    for (int i = 0; i < runs; ++i)
        per_run[i] = run_chain(variant, seed, gpu::uint(i));
    return mean_se(per_run);
}

// ---- The 1-D model of the secondary boundary's reuse ----------------------------------------
//
// The same light and targets, now over the points p^B of edges ("Amortizing Samples in
// Physics-Based Inverse Rendering using ReSTIR", Sec. 5.2, Alg. 6, eq. 27): the quantity is the
// integral over s in [0, 1) (edge points, on k_edges edges of unequal lengths that tile it) of
// the integral over y of h_t(s, y). Each iteration draws k_edge_samples points anew, not one per
// pixel: an edge from a pmf, then a uniform point on it. The pmf is eq. 27's, (mean w_sum / M on
// the edge + eps) times the edge's length (eps: a tenth of the edges' mean), or the length alone
// (unguided). At each point, canonical RIS as above, then one combine with the previous
// iteration's reservoirs nearest to it (at most k_nearest within k_near_radius, ordered by
// distance, ties by index: what a k-d tree or a grid hash built in a fixed order returns), their
// domains being their own points under the previous parameters. The estimate of the integral is
// the mean over the points of h(s, Y) W / p(s), p(s) the density the point was drawn with.
//
// Where the means of eq. 27 come from matters. Taken from the previous iteration's reservoirs, as
// the paper does, the chain is biased (+7 % of the integral here; 96,000 runs: +0.0349, z 28.6):
// a reservoir whose samples came out heavy draws the next points near it, and those points reuse
// it, so which reservoirs are reused, and how often, depends on their own random numbers (the
// selection that dropping empty neighbours makes, above, by another road). Dividing by p(s) does
// not undo it: p(s) cancels in the mean over s of one iteration, not in the chain's. The means
// must come from samples that no reservoir holds: here a pass of its own, canonical RIS at
// k_fresh_points fresh points per edge (96,000 runs: +0.00014, z 0.29). (Means of the previous
// iteration's canonical candidates alone showed no bias either, +0.0009, z 0.86, but those
// candidates are also the reservoirs' samples, so the argument does not cover them.) Two
// deliberate errors must be caught on top of the guide of its own: dividing by the density of the
// unguided pmf while drawing from the guided one, and evaluating a neighbour's own targets (P_ii,
// P_ic) at the current point instead of its own.

constexpr int k_edges = 8, k_edge_samples = 32, k_nearest = 3;
constexpr double k_near_radius = 0.06;
/// The edges' lengths, in twelfths of [0, 1): they tile it in this order.
constexpr int k_edge_twelfths[k_edges] = {1, 2, 1, 3, 1, 1, 2, 1};

enum class EdgeVariant {
    guided,         ///< eq. 27 from the previous reservoirs (the paper's)
    guided_fresh,   ///< the same means from fresh candidates of a pass of its own
    unguided,
    pdf_unguided,   ///< error: guided_fresh's draw divided by the unguided density
    neighbour_here, ///< error: guided_fresh with the neighbours' targets at the current point
};

/// The integral over s in [0, 1) of exact_integral(s, t): midpoint sums on the pieces between the
/// bright part's jumps at |s - 0.3| = 0.12 (kinks elsewhere leave O(h^2), about 1e-9 here).
double edge_integral(int t) {
    static double cached[k_iterations] = {};
    if (cached[t] != 0.0) return cached[t];
    const double cuts[] = {0.0, 0.18, 0.42, 1.0};
    const int cells = 1 << 15;
    double sum = 0;
    for (int piece = 0; piece < 3; ++piece) {
        const double a = cuts[piece], h = (cuts[piece + 1] - a) / cells;
        for (int i = 0; i < cells; ++i)
            sum += exact_integral(a + (i + 0.5) * h, t) * h;
    }
    return cached[t] = sum;
}

/// The mean of canonical RIS weight sums w_sum / M over k_fresh_points points of each edge, drawn
/// with random numbers of their own (stream 2^20 + t of `run`): a guide that no reservoir's
/// sample informs.
constexpr int k_fresh_points = 4;
void fresh_means(gpu::uint seed, gpu::uint run, int t, const double* start, const double* length,
                 double* mean) {
    for (int k = 0; k < k_edges; ++k) {
        mean[k] = 0;
        for (int j = 0; j < k_fresh_points; ++j) {
            gpu::uint dim = 0;
            auto uniform = [&] {
                return gpu::rng_uniform(seed, run, gpu::uint((1 << 20) + t * 1024 + k * 16 + j),
                                        dim++);
            };
            const double s = start[k] + length[k] * double(uniform());
            double w_sum = 0;
            for (int m = 0; m < k_candidates; ++m) {
                const double y = light_sample(uniform());
                w_sum += h0(s, y, t) / light_pdf(y);
            }
            mean[k] += w_sum / k_candidates / k_fresh_points;
        }
    }
}

/// One run of the boundary chain; returns its last iteration's estimate of edge_integral less the
/// integral. Random numbers: rng_uniform(seed, run, t * k_edge_samples + i, dim).
double run_edge_chain(EdgeVariant variant, gpu::uint seed, gpu::uint run) {
    double edge_start[k_edges], edge_length[k_edges];
    for (int k = 0, at = 0; k < k_edges; at += k_edge_twelfths[k++]) {
        edge_start[k] = at / 12.0;
        edge_length[k] = k_edge_twelfths[k] / 12.0;
    }
    std::vector<gpu::Reservoir> prev, cur(k_edge_samples);
    std::vector<float> prev_weight, cur_weight(k_edge_samples); // each reservoir's w_sum / M
    double estimate = 0;
    for (int t = 0; t < k_iterations; ++t) {
        // eq. 27's pmf over the edges, from the previous reservoirs (length alone at first)
        double pmf[k_edges], total_pmf = 0;
        double mean_on[k_edges] = {}, count_on[k_edges] = {}, mean_all = 0;
        for (std::size_t j = 0; j < prev.size(); ++j) {
            mean_on[prev[j].prim] += prev_weight[j];
            count_on[prev[j].prim] += 1;
        }
        for (int k = 0; k < k_edges; ++k)
            if (count_on[k] > 0) mean_on[k] /= count_on[k];
        const bool fresh = variant == EdgeVariant::guided_fresh ||
                           variant == EdgeVariant::pdf_unguided ||
                           variant == EdgeVariant::neighbour_here;
        if (fresh) fresh_means(seed, run, t, edge_start, edge_length, mean_on);
        for (int k = 0; k < k_edges; ++k) mean_all += mean_on[k] / k_edges;
        const bool guided = variant != EdgeVariant::unguided && (fresh || !prev.empty());
        for (int k = 0; k < k_edges; ++k) {
            pmf[k] = (guided ? mean_on[k] + 0.1 * mean_all + 1e-6 : 1.0) * edge_length[k];
            total_pmf += pmf[k];
        }
        estimate = 0;
        for (int i = 0; i < k_edge_samples; ++i) {
            gpu::uint dim = 0;
            auto uniform = [&] {
                return gpu::rng_uniform(seed, run, gpu::uint(t * k_edge_samples + i), dim++);
            };
            // the edge point and its density
            const double u_edge = uniform() * total_pmf;
            int e = 0;
            for (double below = pmf[0]; e + 1 < k_edges && u_edge >= below; below += pmf[++e]) {
            }
            const float s = float(edge_start[e] + edge_length[e] * double(uniform()));
            const double p_s = variant == EdgeVariant::pdf_unguided
                                   ? 1.0 // the length alone: uniform over [0, 1)
                                   : pmf[e] / total_pmf / edge_length[e];
            // 1. canonical RIS with the unshadowed target
            float w_sum = 0.0f, y_c = 0.0f;
            for (int m = 0; m < k_candidates; ++m) {
                const float y = float(light_sample(uniform()));
                const float w = float(h0(s, y, t) / light_pdf(y));
                if (gpu::wrs_update(&w_sum, w, uniform())) y_c = y;
            }
            const double h0_c = h0(s, y_c, t);
            const float W_c = h0_c > 0 ? float(w_sum / (k_candidates * h0_c)) : 0.0f;
            const float P_c = float(h(s, y_c, t));
            // 2. the previous reservoirs nearest to s
            std::vector<int> near;
            for (int j = 0; j < int(prev.size()); ++j)
                if (std::fabs(prev[j].b1 - s) <= k_near_radius) near.push_back(j);
            std::sort(near.begin(), near.end(), [&](int a, int b) {
                const float da = std::fabs(prev[a].b1 - s), db = std::fabs(prev[b].b1 - s);
                return da != db ? da < db : a < b;
            });
            if (near.size() > std::size_t(k_nearest)) near.resize(k_nearest);
            const float M_c = 1.0f;
            float M_sum = M_c;
            for (int j : near) M_sum += std::min(prev[j].M, RESERVOIR_DEFAULT_M_CAP);
            const auto k = gpu::uint(near.size());
            float m_c = gpu::pairwise_mis_canonical_start(M_sum, M_c, k);
            std::vector<float> w(k, 0.0f), y(k, 0.0f);
            for (gpu::uint n = 0; n < k; ++n) {
                const gpu::Reservoir& r = prev[near[n]];
                const float M_i = std::min(r.M, RESERVOIR_DEFAULT_M_CAP);
                // the neighbour's domain: its own point (the error: this one's)
                const double s_i = variant == EdgeVariant::neighbour_here ? s : r.b1;
                m_c += gpu::pairwise_mis_canonical_term(M_i, M_sum, M_c, P_c,
                                                        float(h(s_i, y_c, t - 1)));
                y[n] = r.u1;
                if (gpu::reservoir_is_empty(&r)) continue;
                const float P_ci = float(h(s, r.u1, t));
                const float P_ii = float(h0(s_i, r.u1, t - 1));
                w[n] = gpu::pairwise_mis_neighbour(M_i, M_sum, M_c, P_ii, P_ci) * P_ci * r.W;
            }
            float total = 0.0f, y_pick = 0.0f;
            bool picked = gpu::wrs_update(&total, m_c * P_c * W_c, uniform());
            if (picked) y_pick = y_c;
            for (gpu::uint n = 0; n < k; ++n)
                if (gpu::wrs_update(&total, w[n], uniform())) {
                    picked = true;
                    y_pick = y[n];
                }
            gpu::Reservoir r = gpu::reservoir_empty();
            r.prim = gpu::uint(e);
            r.b1 = s;
            r.M = M_sum;
            const float P_y = picked ? float(h(s, y_pick, t)) : 0.0f;
            if (P_y > 0.0f) {
                r.light = 0;
                r.u1 = y_pick;
                r.W = total / P_y;
                estimate += P_y * r.W / p_s / k_edge_samples;
            }
            cur[i] = r;
            cur_weight[i] = total / M_sum;
        }
        prev = cur;
        prev_weight = cur_weight;
    }
    return estimate - edge_integral(k_iterations - 1);
}

/// The bias of the boundary chain over `runs` independent runs.
MeanSe edge_chain_bias(EdgeVariant variant, gpu::uint seed, int runs) {
    std::vector<double> per_run(runs);
    for (int i = 0; i < runs; ++i)
        per_run[i] = run_edge_chain(variant, seed, gpu::uint(i));
    return mean_se(per_run);
}

} // namespace

TEST_SUITE("reservoir") {
    TEST_CASE("reservoir MIS: pairwise weights sum to 1, and vanish off a neighbour's support") {
        const int trials = 20000;
        double worst = 0;
        int summed = 0, off_support = 0;
        for (int trial = 0; trial < trials; ++trial) {
            const gpu::uint k = gpu::uint(trial % 5), t = gpu::uint(trial);
            // confidences in [1, 20]: integers half the time, as sums of unit confidences are
            const float M_c = 1.0f;
            float M[4], P[4], M_sum = M_c;
            for (gpu::uint i = 0; i < k; ++i) {
                const float u = gpu::rng_uniform(1, t, 2, i);
                M[i] = trial % 2 ? std::floor(1.0f + 20.0f * u) : 1.0f + 19.0f * u;
                M_sum += M[i];
                P[i] = random_target(1, t, 1 + i);
            }
            // For a fixed sample y: P_c = P_c(y), and P[i] = P_i(y) is both neighbour i's
            // own-domain target (P_ii when y is its sample) and its target for the canonical's
            // sample (P_ic when y is the canonical's).
            const float P_c = random_target(1, t, 0);
            float m_c = gpu::pairwise_mis_canonical_start(M_sum, M_c, k);
            for (gpu::uint i = 0; i < k; ++i)
                m_c += gpu::pairwise_mis_canonical_term(M[i], M_sum, M_c, P_c, P[i]);
            double sum = m_c;
            for (gpu::uint j = 0; j < k; ++j) {
                const float m_j = gpu::pairwise_mis_neighbour(M[j], M_sum, M_c, P[j], P_c);
                INFO("trial " << trial << ", neighbour " << j << ": M " << M[j] << ", P_j " << P[j]
                              << ", P_c " << P_c);
                CHECK(m_j >= 0.0f);
                CHECK(m_j <= M[j] / M_sum * (1.0f + 1e-6f));
                if (P[j] == 0.0f) {
                    CHECK(m_j == 0.0f); // off neighbour j's support: exactly 0
                    ++off_support;
                }
                sum += m_j;
            }
            if (k == 0) CHECK(m_c == 1.0f);
            // Where the canonical target is 0 the integrand is 0 too (h <= P_c), so no sum is
            // required there; the canonical's resampling weight m_c P_c W_c is 0 by its factor
            // P_c, whatever m_c (which keeps M_c / M_sum) is.
            if (P_c > 0.0f) {
                worst = std::max(worst, std::fabs(sum - 1.0));
                ++summed;
            }
        }
        MESSAGE("worst |sum - 1| " << worst << " over " << summed << " samples; " << off_support
                                   << " neighbour weights off their support");
        CHECK(summed > trials / 2);
        CHECK(off_support > 1000);
        CHECK(worst < 1e-6);
    }

    TEST_CASE("reservoir WRS: streaming WRS picks each candidate with probability w_i / sum w") {
        const std::vector<float> w = {0.0f, 2.0f, 0.5f, 0.0f, 7.0f, 1.0f, 0.0f, 3.0f, 0.125f, 0.0f};
        const int n = 200000;
        // rule(&sum, w, coin): the shared one, and a wrong one that tests the coin against the
        // sum before w is added (so a late candidate wins too often)
        auto wrong = [](float* sum, float wi, float coin) {
            if (!(wi > 0.0f)) return 0;
            const float before = *sum;
            *sum += wi;
            return int(coin * before <= wi);
        };
        auto frequencies = [&](auto rule, gpu::uint seed, float* final_sum) {
            std::vector<double> count(w.size() + 1, 0.0); // the last: nothing picked
            for (int s = 0; s < n; ++s) {
                float sum = 0.0f;
                std::size_t pick = w.size();
                for (std::size_t i = 0; i < w.size(); ++i)
                    if (rule(&sum, w[i], gpu::rng_uniform(seed, gpu::uint(s), 0, gpu::uint(i))))
                        pick = i;
                count[pick] += 1.0;
                *final_sum = sum;
            }
            return count;
        };
        double total = 0;
        for (float wi : w)
            total += wi;
        // max |z| over the indices of positive weight
        auto worst_z = [&](const std::vector<double>& count) {
            double worst = 0;
            for (std::size_t i = 0; i < w.size(); ++i) {
                if (w[i] == 0.0f) continue;
                const double p = w[i] / total, se = std::sqrt(p * (1 - p) / n);
                worst = std::max(worst, std::fabs(count[i] / n - p) / se);
            }
            return worst;
        };
        float sum = 0.0f;
        const std::vector<double> count = frequencies(gpu::wrs_update, 21, &sum);
        CHECK(sum == float(total));    // zero weights do not change the sum (exact here)
        CHECK(count[w.size()] == 0.0); // something positive is always picked
        for (std::size_t i = 0; i < w.size(); ++i) {
            INFO("index " << i << ": weight " << w[i] << ", frequency " << count[i] / n);
            if (w[i] == 0.0f) CHECK(count[i] == 0.0);
        }
        const double z = worst_z(count);
        float ignored;
        const double z_wrong = worst_z(frequencies(wrong, 21, &ignored));
        MESSAGE("worst |z| of the pick frequencies " << z << "; of the wrong rule " << z_wrong);
        CHECK(z < 4.0);
        CHECK(z_wrong > 10.0);

        // edge cases: a first positive candidate wins even with the largest coin; zero,
        // negative and NaN weights neither win nor change the sum
        float s = 0.0f;
        CHECK(gpu::wrs_update(&s, 1e-30f, 1.0f - 1.0f / 16777216.0f) == 1);
        s = 2.0f;
        CHECK(gpu::wrs_update(&s, 0.0f, 0.0f) == 0);
        CHECK(gpu::wrs_update(&s, -1.0f, 0.0f) == 0);
        CHECK(gpu::wrs_update(&s, std::nanf(""), 0.0f) == 0);
        CHECK(s == 2.0f);
    }

    TEST_CASE("reservoir 1-D model: the closed-form integral matches quadrature") {
        // The midpoint rule on 2^16 cells is good to ~1e-4 here (the integrand jumps at 4 points).
        for (int i = 0; i < 16; ++i) {
            const double x = (i + 0.37) / 16.0;
            const int cells = 1 << 16;
            double sum = 0;
            for (int c = 0; c < cells; ++c)
                sum += h(x, (c + 0.5) / cells, 3);
            INFO("x " << x);
            CHECK(exact_integral(x, 3) == doctest::Approx(sum / cells).epsilon(2e-4));
        }
    }

    TEST_CASE(
        "reservoir 1-D model: the chain on the shared code is unbiased, and the test has power") {
        const int runs = 8000;
        const auto start = std::chrono::steady_clock::now();
        double mean_integral = 0;
        for (int p = 0; p < k_pixels; ++p)
            mean_integral += exact_integral((p + 0.5) / k_pixels, k_iterations - 1) / k_pixels;
        const MeanSe shadowed = chain_bias(Variant::shadowed, 101, runs);
        const MeanSe cheap = chain_bias(Variant::cheap, 102, runs);
        const MeanSe no_v = chain_bias(Variant::unshadowed_support, 103, runs);
        const MeanSe dropped = chain_bias(Variant::drop_empty, 104, runs);
        const double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        auto show = [](const MeanSe& m) {
            return std::to_string(m.mean) + " (z " + std::to_string(m.z()) + ")";
        };
        MESSAGE("mean integral " << mean_integral << "; bias over " << runs << " runs: shadowed "
                                 << show(shadowed) << ", cheap mode " << show(cheap)
                                 << ", support without V " << show(no_v)
                                 << ", empty neighbours dropped " << show(dropped) << "; "
                                 << seconds << " s");
        CHECK(std::fabs(shadowed.z()) < 4.0);
        CHECK(std::fabs(cheap.z()) < 4.0);
        CHECK(std::fabs(no_v.z()) > 10.0);
        CHECK(std::fabs(dropped.z()) > 10.0);
    }

    TEST_CASE("reservoir 1-D model: the boundary's chain over guided edge points is unbiased with "
              "a guide of its own, and the test has power") {
        const int runs = 16000;
        const auto start = std::chrono::steady_clock::now();
        const MeanSe fresh = edge_chain_bias(EdgeVariant::guided_fresh, 201, runs);
        const MeanSe unguided = edge_chain_bias(EdgeVariant::unguided, 202, runs);
        const MeanSe wrong_pdf = edge_chain_bias(EdgeVariant::pdf_unguided, 203, runs);
        const MeanSe here = edge_chain_bias(EdgeVariant::neighbour_here, 204, runs);
        const MeanSe reused = edge_chain_bias(EdgeVariant::guided, 205, runs);
        const double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        auto show = [](const MeanSe& m) {
            return std::to_string(m.mean) + " (z " + std::to_string(m.z()) + ")";
        };
        MESSAGE("integral " << edge_integral(k_iterations - 1) << "; bias over " << runs
                            << " runs: guide of its own " << show(fresh) << ", unguided "
                            << show(unguided) << ", unguided density " << show(wrong_pdf)
                            << ", neighbours' targets here " << show(here)
                            << ", guide from the reused reservoirs " << show(reused) << "; "
                            << seconds << " s");
        CHECK(std::fabs(fresh.z()) < 4.0);
        CHECK(std::fabs(unguided.z()) < 4.0);
        CHECK(std::fabs(wrong_pdf.z()) > 10.0);
        CHECK(std::fabs(here.z()) > 10.0);
        // eq. 27 as the paper has it: biased (the model's header says why)
        CHECK(reused.z() > 6.0);
    }
}
