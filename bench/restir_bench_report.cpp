// The error measures and the report of `tandem bench restir`.
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>

#include "bench/restir_bench.h"
#include "bench/restir_stats.h"

namespace tandem {

double median(std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

RestirBlocks::RestirBlocks(std::size_t elements, int width, int height, int channels) {
    of.resize(elements);
    if (width <= 0 || height <= 0 || channels <= 0 ||
        std::size_t(width) * height * channels != elements) {
        for (std::size_t j = 0; j < elements; ++j)
            of[j] = int(j);
        count = int(elements);
        return;
    }
    const int bw = (width + k_block - 1) / k_block, bh = (height + k_block - 1) / k_block;
    for (std::size_t j = 0; j < elements; ++j) {
        const int texel = int(j / channels), x = texel % width, y = texel / width;
        of[j] = (y / k_block) * bw + x / k_block;
    }
    count = bw * bh;
}

std::vector<double> RestirBlocks::sums(const std::vector<float>& g) const {
    std::vector<double> s(count, 0.0);
    for (std::size_t j = 0; j < g.size(); ++j)
        s[of[j]] += g[j];
    return s;
}

namespace {

/// The mean over `v` and its standard error.
double mean_se(const std::vector<double>& v, double* se) {
    const double k = double(v.size());
    double m = 0.0, s = 0.0;
    for (double x : v)
        m += x / k;
    for (double x : v)
        s += (x - m) * (x - m);
    *se = v.size() > 1 ? std::sqrt(s / (k - 1.0) / k) : 0.0;
    return m;
}

/// Per block b of `sums` (one vector per seed or chunk): the mean and its standard error.
void block_stats(const std::vector<std::vector<double>>& sums, std::vector<double>* mean,
                 std::vector<double>* se) {
    const std::size_t blocks = sums.at(0).size();
    mean->assign(blocks, 0.0);
    se->assign(blocks, 0.0);
    std::vector<double> column(sums.size());
    for (std::size_t b = 0; b < blocks; ++b) {
        for (std::size_t k = 0; k < sums.size(); ++k)
            column[k] = sums[k][b];
        (*mean)[b] = mean_se(column, &(*se)[b]);
    }
}

} // namespace

RestirReference make_reference(const std::vector<std::vector<float>>& chunks,
                               const RestirBlocks& blocks) {
    RestirReference r;
    const std::size_t n = chunks.at(0).size(), c = chunks.size();
    r.mean.assign(n, 0.0);
    r.var.assign(n, 0.0);
    for (const auto& g : chunks)
        for (std::size_t j = 0; j < n; ++j)
            r.mean[j] += g[j] / double(c);
    if (c > 1)
        for (const auto& g : chunks)
            for (std::size_t j = 0; j < n; ++j) {
                const double d = g[j] - r.mean[j];
                r.var[j] += d * d / double(c - 1) / double(c); // variance of the mean
            }
    double var_sum = 0.0;
    for (std::size_t j = 0; j < n; ++j)
        r.norm2 += r.mean[j] * r.mean[j], var_sum += r.var[j];
    r.eps = 1e-2 * r.norm2 / double(n);
    for (std::size_t j = 0; j < n; ++j)
        r.floor += r.var[j] / (r.mean[j] * r.mean[j] + r.eps) / double(n);
    r.rel_l2 = r.norm2 > 0.0 ? std::sqrt(var_sum / r.norm2) : 0.0;
    std::vector<double> sums;
    std::vector<std::vector<double>> block_sums;
    for (const auto& g : chunks) {
        double sum = 0.0;
        for (float x : g)
            sum += x;
        sums.push_back(sum);
        block_sums.push_back(blocks.sums(g));
    }
    r.sum = mean_se(sums, &r.sum_se);
    r.blocks = blocks;
    block_stats(block_sums, &r.block_mean, &r.block_se);
    return r;
}

void measure_estimate(const std::vector<std::vector<float>>& grads, const RestirReference& ref,
                      RestirEstimate* e) {
    const std::size_t n = ref.mean.size(), k = grads.size();
    std::vector<double> relmse, sums;
    std::vector<std::vector<double>> block_sums;
    double rel_l2 = 0.0;
    for (const auto& g : grads) {
        double r = 0.0, d2 = 0.0, sum = 0.0;
        for (std::size_t j = 0; j < n; ++j) {
            const double d = g[j] - ref.mean[j];
            r += d * d / (ref.mean[j] * ref.mean[j] + ref.eps);
            d2 += d * d;
            sum += g[j];
        }
        relmse.push_back(r / double(n));
        sums.push_back(sum);
        block_sums.push_back(ref.blocks.sums(g));
        rel_l2 += std::sqrt(d2 / ref.norm2) / double(k);
    }
    e->relmse = mean_se(relmse, &e->relmse_se);
    e->rel_l2 = rel_l2;
    double sum_se = 0.0;
    const double sum = mean_se(sums, &sum_se);
    e->sum_ratio = sum / ref.sum;
    const double se = std::hypot(sum_se, ref.sum_se);
    e->sum_z = se > 0.0 ? (sum - ref.sum) / se : 0.0;
    e->block_z_mean = e->block_z_mean_abs = e->block_z_beyond_3 =
        std::numeric_limits<double>::quiet_NaN();
    if (k < 2) return;
    std::vector<double> mean, bse;
    block_stats(block_sums, &mean, &bse);
    double z_sum = 0.0, z_abs = 0.0, beyond = 0.0, counted = 0.0;
    for (std::size_t b = 0; b < mean.size(); ++b) {
        const double s = std::hypot(bse[b], ref.block_se[b]);
        if (!(s > 0.0)) continue; // no spread: a block no sample reaches
        const double z = (mean[b] - ref.block_mean[b]) / s;
        z_sum += z, z_abs += std::fabs(z), beyond += std::fabs(z) > 3.0, counted += 1.0;
    }
    if (counted > 0.0) {
        e->block_z_mean = z_sum / counted;
        e->block_z_mean_abs = z_abs / counted;
        e->block_z_beyond_3 = beyond / counted;
    }
}

nlohmann::json RestirEstimate::to_json() const {
    auto num = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); };
    return {{"name", name},
            {"config", config},
            {"spp", spp},
            {"seconds", seconds},
            {"restir_seconds", restir_seconds},
            {"adjoint_seconds", adjoint_seconds},
            {"burn_in_seconds", burn_in_seconds},
            {"seeds", seeds},
            {"relmse", relmse},
            {"relmse_se", relmse_se},
            {"rel_l2", rel_l2},
            {"sum_ratio", sum_ratio},
            {"sum_z", sum_z},
            {"block_z_mean", num(block_z_mean)},
            {"block_z_mean_abs", num(block_z_mean_abs)},
            {"block_z_beyond_3", num(block_z_beyond_3)}};
}

const RestirEstimate* RestirPoint::find(const std::string& name) const {
    for (const RestirEstimate& e : estimates)
        if (e.name == name) return &e;
    return nullptr;
}

double RestirPoint::ratio(const std::string& base, const std::string& of) const {
    return find(base)->relmse / find(of)->relmse;
}

double RestirPoint::ratio_se(const std::string& base) const {
    const RestirEstimate *b = find(base), *r = find("restir");
    return ratio(base) * std::hypot(b->relmse_se / b->relmse, r->relmse_se / r->relmse);
}

double RestirPoint::ratio_corrected(const std::string& base) const {
    return (find(base)->relmse - reference_floor) / (find("restir")->relmse - reference_floor);
}

double RestirPoint::efficiency(const std::string& base) const {
    const RestirEstimate *b = find(base), *r = find("restir");
    return b->relmse * b->seconds / (r->relmse * r->seconds);
}

nlohmann::json RestirPoint::to_json() const {
    nlohmann::json est = nlohmann::json::array();
    for (const RestirEstimate& e : estimates)
        est.push_back(e.to_json());
    nlohmann::json ratios = nlohmann::json::object();
    for (const char* base : {"prb", "ris", "prb_equal_spp", "ris_equal_spp"})
        ratios[base] = {{"relmse_ratio", ratio(base)},
                        {"relmse_ratio_se", ratio_se(base)},
                        {"relmse_ratio_corrected", ratio_corrected(base)},
                        {"time_ratio", find(base)->seconds / find("restir")->seconds},
                        {"efficiency", efficiency(base)}};
    return {{"t", t},
            {"loss", loss},
            {"reference_spp", reference_spp},
            {"eps", eps},
            {"reference_floor", reference_floor},
            {"reference_rel_l2", reference_rel_l2},
            {"boundary_reference_floor", boundary_reference_floor},
            {"estimators", est},
            {"versus", ratios}};
}

const RestirPoint* RestirCase::at(int t) const {
    for (const RestirPoint& p : points)
        if (p.t == t) return &p;
    return nullptr;
}

nlohmann::json RestirCase::to_json() const {
    nlohmann::json pts = nlohmann::json::array();
    for (const RestirPoint& p : points)
        pts.push_back(p.to_json());
    nlohmann::json defs = nlohmann::json::object(); // -D name=value: which variant was measured
    for (const auto& [k, v] : defines)
        defs[k] = v;
    return {{"name", name},   {"scene", scene},         {"defines", defs},
            {"param", param}, {"max_depth", max_depth}, {"shapes", shapes}, {"points", pts}};
}

nlohmann::json RestirBenchResult::to_json() const {
    nlohmann::json j = {{"device", device},
                        {"res", res},
                        {"seeds", seeds},
                        {"spp_grad", spp_grad},
                        {"delta_spp", delta_spp},
                        {"target_spp", target_spp},
                        {"reference_factor", reference_factor},
                        {"wall_seconds", wall_seconds}};
    nlohmann::json cs = nlohmann::json::array();
    for (const RestirCase& c : cases)
        cs.push_back(c.to_json());
    j["cases"] = cs;
    // the headline: the last t of each case
    auto last = [](const RestirCase& c) { return &c.points.back(); };
    if (!cases.empty()) {
        const RestirPoint* p = last(cases[0]);
        j["t"] = p->t;
        j["relmse_vs_prb"] = p->ratio("prb");
        j["relmse_vs_ris"] = p->ratio("ris");
        j["relmse_vs_prb_se"] = p->ratio_se("prb");
        j["relmse_vs_ris_se"] = p->ratio_se("ris");
        j["relmse_vs_prb_corrected"] = p->ratio_corrected("prb");
        j["relmse_vs_ris_corrected"] = p->ratio_corrected("ris");
        j["efficiency_vs_prb"] = p->efficiency("prb");
        j["efficiency_vs_ris"] = p->efficiency("ris");
        j["seconds_restir"] = p->find("restir")->seconds;
        j["seconds_prb"] = p->find("prb")->seconds;
        j["seconds_ris"] = p->find("ris")->seconds;
        if (cases[0].shapes) { // the shape gradient's protocol: plain is PRB's estimator
            j["relmse_vs_plain"] = p->ratio("prb");
            j["relmse_vs_plain_boundary"] = p->ratio("prb_boundary", "restir_boundary");
            j["seconds_plain"] = p->find("prb")->seconds;
        }
    }
    for (std::size_t i = 1; i < cases.size(); ++i) {
        const RestirPoint* p = last(cases[i]);
        if (cases[i].name == "negative_control") {
            j["negative_control_efficiency"] = p->efficiency("prb");
            j["negative_control_relmse_vs_prb"] = p->ratio("prb");
            j["negative_control_time_ratio"] =
                p->find("restir")->seconds / p->find("prb_equal_spp")->seconds;
        } else {
            const std::string suffix = "_depth" + std::to_string(cases[i].max_depth);
            j["relmse_vs_prb" + suffix] = p->ratio("prb");
            j["relmse_vs_prb" + suffix + "_se"] = p->ratio_se("prb");
            j["relmse_vs_ris" + suffix] = p->ratio("ris");
            j["efficiency_vs_prb" + suffix] = p->efficiency("prb");
        }
    }
    if (!ablations.empty()) {
        nlohmann::json a = nlohmann::json::array();
        for (const RestirEstimate& e : ablations)
            a.push_back(e.to_json());
        j["ablation_t"] = ablation_t;
        j["ablations"] = a;
    }
    return j;
}

std::string RestirBenchResult::to_table() const {
    std::ostringstream s;
    s << "device " << device << ", " << res << "x" << res << ", " << seeds
      << " seeds, ReSTIR spp_grad " << spp_grad << ", delta from " << delta_spp << " spp, wall "
      << std::fixed << std::setprecision(0) << wall_seconds << " s\n";
    auto sci = [](double v) {
        std::ostringstream o;
        o << std::scientific << std::setprecision(3) << v;
        return o.str();
    };
    s << std::fixed;
    for (const RestirCase& c : cases) {
        s << "\n" << c.name << ": " << c.scene;
        for (const auto& [k, v] : c.defines)
            s << " -D " << k << "=" << v;
        s << ", " << c.param << ", max_depth " << c.max_depth << "\n";
        for (const RestirPoint& p : c.points) {
            s << "t = " << p.t << ": loss " << sci(p.loss) << ", reference " << p.reference_spp
              << " spp (its own relMSE " << sci(p.reference_floor) << ", rel L2 "
              << std::setprecision(3) << p.reference_rel_l2 << ")\n";
            s << "| estimator | spp | a pass alone s | adjoint (pass fused) s | s/iter | relMSE | "
                 "± se | rel L2 | sum ratio (z) | block z: mean, mean abs, > 3 |\n"
                 "|---|---|---|---|---|---|---|---|---|---|\n";
            for (const RestirEstimate& e : p.estimates)
                s << "| " << e.name << " | " << e.spp << " | " << std::setprecision(4)
                  << e.restir_seconds << " | " << e.adjoint_seconds << " | " << e.seconds << " | "
                  << sci(e.relmse) << " | " << sci(e.relmse_se) << " | " << std::setprecision(3)
                  << e.rel_l2 << " | " << e.sum_ratio << " (" << std::setprecision(1) << e.sum_z
                  << ") | " << std::setprecision(2) << e.block_z_mean << ", " << e.block_z_mean_abs
                  << ", " << std::setprecision(1) << 100.0 * e.block_z_beyond_3 << " % |\n";
            s << std::setprecision(2) << "relMSE over ReSTIR's: PRB " << p.ratio("prb") << " ± "
              << p.ratio_se("prb") << " (reference noise removed " << p.ratio_corrected("prb")
              << ", efficiency " << p.efficiency("prb") << "), RIS " << p.ratio("ris") << " ± "
              << p.ratio_se("ris") << " (removed " << p.ratio_corrected("ris") << ", efficiency "
              << p.efficiency("ris") << "), PRB at equal spp " << p.ratio("prb_equal_spp") << "\n";
        }
    }
    if (!ablations.empty()) {
        const RestirPoint* p = cases[0].at(ablation_t);
        const RestirEstimate* prb = p ? p->find("prb") : nullptr;
        s << "\nablations at t = " << ablation_t << " (" << cases[0].name << ")\n"
          << "| variant | a pass alone s | adjoint (pass fused) s | s/iter | relMSE | ± se | "
             "rel L2 | efficiency vs PRB |\n"
          << "|---|---|---|---|---|---|---|---|\n";
        for (const RestirEstimate& e : ablations)
            s << "| " << e.name << " | " << std::setprecision(4) << e.restir_seconds << " | "
              << e.adjoint_seconds << " | " << e.seconds << " | " << sci(e.relmse) << " | "
              << sci(e.relmse_se) << " | " << std::setprecision(3) << e.rel_l2 << " | "
              << std::setprecision(2)
              << (prb ? prb->relmse * prb->seconds / (e.relmse * e.seconds) : 0.0) << " |\n";
    }
    return s.str();
}

} // namespace tandem
