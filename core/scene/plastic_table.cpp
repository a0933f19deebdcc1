// roughplastic's rough-interface tables: Mitsuba 3's quadratures in double, over the alpha grid.
#include "core/scene/plastic_table.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>
#include <memory>
#include <mutex>
#include <thread>

#include "shared/plastic_table.h"

namespace tandem {

namespace {

constexpr double kPi = 3.14159265358979323846;

/// The Legendre polynomial P_n(z) and its derivative, by the three-term recurrence.
double legendre(int n, double z, double* derivative) {
    double p0 = 1.0, p1 = z;
    for (int k = 2; k <= n; ++k) {
        const double p2 = ((2 * k - 1) * z * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
    }
    *derivative = n * (z * p1 - p0) / (z * z - 1.0);
    return p1;
}

/// Gauss-Legendre rule of n nodes on [0, 1] (Newton on P_n from the usual initial guesses).
void gauss_legendre(int n, std::vector<double>& x, std::vector<double>& w) {
    x.resize(n);
    w.resize(n);
    for (int i = 0; i < n; ++i) {
        double z = std::cos(kPi * (i + 0.75) / (n + 0.5)), dp = 1.0;
        for (int it = 0; it < 100; ++it) {
            const double dz = legendre(n, z, &dp) / dp;
            z -= dz;
            if (std::fabs(dz) < 1e-15) break;
        }
        legendre(n, z, &dp);
        x[i] = 0.5 * z + 0.5;
        w[i] = 1.0 / ((1.0 - z * z) * dp * dp); // 2 / ((1 - z^2) P'^2), halved for [0, 1]
    }
}

/// The res x res product rule on the sample square, folded in half: with phi = 2 pi u2 + pi / 2
/// the mirror u2 -> 1 - u2 maps the sampled normal m to (m.x, -m.y, m.z) when wi.y = 0, which
/// leaves every integrand here unchanged, so the nodes with u2 < 1/2 count twice.
struct SquareRule {
    std::vector<double> radius, weight_r;           // sqrt(u1) and its weight
    std::vector<double> cos_phi, sin_phi, weight_p; // u2 < 1/2, weights doubled
    explicit SquareRule(int res) {
        std::vector<double> x, w;
        gauss_legendre(res, x, w);
        for (int i = 0; i < res; ++i) {
            radius.push_back(std::sqrt(x[i]));
            weight_r.push_back(w[i]);
            if (x[i] < 0.5) {
                cos_phi.push_back(-std::sin(2.0 * kPi * x[i]));
                sin_phi.push_back(std::cos(2.0 * kPi * x[i]));
                weight_p.push_back(2.0 * w[i]);
            }
        }
    }
};

const SquareRule& square_rule(int res) {
    static std::mutex mutex;
    static std::map<int, std::unique_ptr<SquareRule>> rules;
    const std::lock_guard<std::mutex> lock(mutex);
    std::unique_ptr<SquareRule>& r = rules[res];
    if (!r) r = std::make_unique<SquareRule>(res);
    return *r;
}

/// Mitsuba's GGX smith_g1(v, m) (0 when v sees the back of m).
double smith_g1(double alpha, double vx, double vy, double vz, double mx, double my, double mz) {
    if ((vx * mx + vy * my + vz * mz) * vz <= 0.0) return 0.0;
    const double xy = alpha * alpha * (vx * vx + vy * vy);
    if (xy == 0.0) return 1.0;
    return 2.0 / (1.0 + std::sqrt(1.0 + xy / (vz * vz)));
}

/// The integral over the sample square of the visible normals of wi = (sin, 0, cos_theta) of
/// (1 - F) G1(wo) with wo refracted below (transmit), or F G1(wo) with wo reflected above.
double interface_integral(double alpha, double cos_theta, double eta, bool transmit, int res) {
    const SquareRule& q = square_rule(res);
    const double mu = cos_theta, st = std::sqrt(std::max(0.0, 1.0 - mu * mu));
    // Heitz 2018: the stretched view direction vh and the frame (t1, t2) around it
    const double len = std::sqrt(alpha * alpha * st * st + mu * mu);
    const double vx = alpha * st / len, vz = mu / len;
    const bool pole = !(vx > 0.0);
    const double t1x = pole ? 1.0 : 0.0, t1y = pole ? 0.0 : 1.0;  // (-vh.y, vh.x, 0) normalised
    const double t2x = -vz * t1y, t2y = vz * t1x, t2z = vx * t1y; // vh x t1
    const double s = 0.5 * (1.0 + vz);
    const double eta_it = eta, eta_ti = 1.0 / eta; // wi is outside the interface's eta
    double total = 0.0;
    for (std::size_t i = 0; i < q.radius.size(); ++i) {
        const double r = q.radius[i];
        double row = 0.0;
        for (std::size_t j = 0; j < q.cos_phi.size(); ++j) {
            const double p1 = r * q.cos_phi[j];
            const double p2 =
                (1.0 - s) * std::sqrt(std::max(0.0, 1.0 - p1 * p1)) + s * r * q.sin_phi[j];
            const double z = std::sqrt(std::max(0.0, 1.0 - p1 * p1 - p2 * p2));
            double mx = alpha * (t1x * p1 + t2x * p2 + vx * z);
            double my = alpha * (t1y * p1 + t2y * p2);
            double mz = std::max(0.0, t2z * p2 + vz * z);
            const double inv = 1.0 / std::sqrt(mx * mx + my * my + mz * mz);
            mx *= inv, my *= inv, mz *= inv;
            // Mitsuba's fresnel(wi.m, eta): reflectance and the signed cosine of the refraction
            const double c = st * mx + mu * mz, ac = std::fabs(c);
            const double it = c >= 0.0 ? eta_it : 1.0 / eta_it, ti = c >= 0.0 ? eta_ti : eta;
            const double ct2 = 1.0 - (1.0 - c * c) * ti * ti;
            const double ct_abs = std::sqrt(std::max(0.0, ct2));
            double f = 1.0;
            if (eta == 1.0)
                f = 0.0;
            else if (ac > 0.0) {
                const double a_s = (ac - it * ct_abs) / (ac + it * ct_abs);
                const double a_p = (ct_abs - it * ac) / (ct_abs + it * ac);
                f = 0.5 * (a_s * a_s + a_p * a_p);
            }
            double ox, oy, oz, value;
            if (transmit) { // Mitsuba's refract: m (wi.m eta_ti + cos_theta_t) - wi eta_ti
                const double ct = c >= 0.0 ? -ct_abs : ct_abs, k = c * ti + ct;
                ox = mx * k - st * ti, oy = my * k, oz = mz * k - mu * ti;
                if (oz * mu >= 0.0) continue;
                value = 1.0 - f;
            } else {
                ox = 2.0 * c * mx - st, oy = 2.0 * c * my, oz = 2.0 * c * mz - mu;
                if (oz <= 0.0 || mu <= 0.0) continue;
                value = f;
            }
            row += q.weight_p[j] * value * smith_g1(alpha, ox, oy, oz, mx, my, mz);
        }
        total += q.weight_r[i] * row;
    }
    return total;
}

/// The cosine of Mitsuba's table node k.
double mu_node(unsigned k) {
    return std::max(1e-6, k / double(PLASTIC_MU_NODES - 1u));
}

/// Slopes of the complete cubic spline through y on a grid of spacing h, end slopes from
/// second-order one-sided differences.
std::vector<double> spline_slopes(const std::vector<double>& y, double h) {
    const std::size_t n = y.size();
    std::vector<double> m(n), diag(n, 4.0), rhs(n);
    m[0] = (-3.0 * y[0] + 4.0 * y[1] - y[2]) / (2.0 * h);
    m[n - 1] = (3.0 * y[n - 1] - 4.0 * y[n - 2] + y[n - 3]) / (2.0 * h);
    // interior: m[i-1] + 4 m[i] + m[i+1] = 3 (y[i+1] - y[i-1]) / h, a tridiagonal solve
    for (std::size_t i = 1; i + 1 < n; ++i)
        rhs[i] = 3.0 * (y[i + 1] - y[i - 1]) / h;
    rhs[1] -= m[0];
    rhs[n - 2] -= m[n - 1];
    for (std::size_t i = 2; i + 1 < n; ++i) {
        const double w = 1.0 / diag[i - 1];
        diag[i] -= w;
        rhs[i] -= w * rhs[i - 1];
    }
    for (std::size_t i = n - 2; i >= 1; --i)
        m[i] = (rhs[i] - (i + 2 < n ? m[i + 1] : 0.0)) / diag[i];
    return m;
}

/// alpha of grid variable s.
double alpha_of(double s) {
    return s * s * s * s;
}

std::vector<float> build_table(double eta) {
    const unsigned n = PLASTIC_ALPHAS;
    const double h = PLASTIC_DS;
    std::vector<double> r(n);
    std::vector<float> table(PLASTIC_TABLE_FLOATS);
    const int res_t = plastic_transmittance_res(eta), res_r = plastic_reflectance_res(eta);
    auto fill_row = [&](unsigned j) {
        const double s = PLASTIC_S_MIN + j * h, e = 1e-4;
        float* row = &table[j * PLASTIC_ROW];
        for (unsigned k = 0; k < PLASTIC_MU_NODES; ++k) {
            const double mu = mu_node(k);
            const double lo = rough_dielectric_transmittance(alpha_of(s - e), mu, eta, res_t);
            const double hi = rough_dielectric_transmittance(alpha_of(s + e), mu, eta, res_t);
            row[2 * k] = (float)rough_dielectric_transmittance(alpha_of(s), mu, eta, res_t);
            row[2 * k + 1] = (float)(h * (hi - lo) / (2.0 * e));
        }
        r[j] = rough_internal_reflectance(alpha_of(s), eta, res_r);
    };
    // rows are independent: split them over the cores (the result does not depend on how)
    const unsigned threads = std::max(1u, std::min(n, std::thread::hardware_concurrency()));
    std::vector<std::thread> pool;
    for (unsigned t = 0; t < threads; ++t)
        pool.emplace_back([&, t] {
            for (unsigned j = t; j < n; j += threads)
                fill_row(j);
        });
    for (std::thread& th : pool)
        th.join();
    const std::vector<double> slopes = spline_slopes(r, h);
    for (unsigned j = 0; j < n; ++j) {
        table[j * PLASTIC_ROW + 2 * PLASTIC_MU_NODES] = (float)r[j];
        table[j * PLASTIC_ROW + 2 * PLASTIC_MU_NODES + 1] = (float)(h * slopes[j]);
    }
    return table;
}

} // namespace

double rough_dielectric_transmittance(double alpha, double cos_theta, double eta, int res) {
    return interface_integral(alpha, cos_theta, eta, true, res);
}

double rough_dielectric_reflectance(double alpha, double cos_theta, double eta, int res) {
    return interface_integral(alpha, cos_theta, eta, false, res);
}

double rough_internal_reflectance(double alpha, double eta, int res) {
    double sum = 0.0;
    for (unsigned k = 0; k < PLASTIC_MU_NODES; ++k)
        sum += rough_dielectric_reflectance(alpha, mu_node(k), 1.0 / eta, res) * mu_node(k);
    return 2.0 * sum / PLASTIC_MU_NODES;
}

int plastic_transmittance_res(double eta) {
    return eta > 1.0 ? 32 : 64;
}

int plastic_reflectance_res(double eta) {
    return 1.0 / eta > 1.0 ? 32 : 64;
}

const std::vector<float>& plastic_table(float eta) {
    static std::mutex mutex;
    static std::map<std::uint32_t, std::unique_ptr<std::vector<float>>> tables;
    std::uint32_t key;
    std::memcpy(&key, &eta, sizeof key);
    const std::lock_guard<std::mutex> lock(mutex);
    std::unique_ptr<std::vector<float>>& t = tables[key];
    if (!t) t = std::make_unique<std::vector<float>>(build_table(eta));
    return *t;
}

} // namespace tandem
