// Metrics of `tandem optimize`.
#include "core/inverse/metrics.h"

#include <cmath>
#include <iomanip>
#include <sstream>

#include "core/io/plot.h"

namespace tandem {

std::string metrics_csv(const std::vector<MetricsRow>& rows) {
    std::string s = "iteration,seconds,loss,param_error,image_error,alpha_mean,inputs_changed\n";
    for (const MetricsRow& r : rows)
        s += metrics_csv_row(r);
    return s;
}

std::string metrics_csv_row(const MetricsRow& r) {
    std::ostringstream s;
    s << std::setprecision(9) << r.iteration << ',' << r.seconds << ',' << r.loss << ',';
    if (r.param_error >= 0.0) s << r.param_error;
    s << ',';
    if (r.image_error >= 0.0) s << r.image_error;
    s << ',';
    if (r.alpha_mean >= 0.0) s << r.alpha_mean;
    s << ',';
    if (r.inputs_changed) s << 1;
    s << '\n';
    return s.str();
}

void write_convergence_plot(const std::string& path, const std::vector<MetricsRow>& rows) {
    PlotSeries loss{"loss", {}, {}}, perr{"parameter RMSE", {}, {}}, ierr{"image RMSE", {}, {}};
    for (const MetricsRow& r : rows) {
        loss.x.push_back(r.iteration);
        loss.y.push_back(r.loss);
        if (r.param_error >= 0.0) perr.x.push_back(r.iteration), perr.y.push_back(r.param_error);
        if (r.image_error >= 0.0) ierr.x.push_back(r.iteration), ierr.y.push_back(r.image_error);
    }
    PlotOptions opt;
    opt.title = "convergence";
    opt.y_label = "error";
    write_plot(path, {loss, perr, ierr}, opt);
}

double rmse(const std::vector<float>& a, const std::vector<float>& b) {
    double s = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i)
        s += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
    return a.empty() ? 0.0 : std::sqrt(s / double(a.size()));
}

double image_rmse(const std::vector<float>& a, const std::vector<float>& b,
                  const std::vector<float>& mask) {
    if (mask.empty()) return rmse(a, b);
    double s = 0.0, weight = 0.0;
    for (std::size_t p = 0; p < mask.size(); ++p) {
        for (std::size_t c = 3 * p; c < 3 * p + 3; ++c)
            s += double(mask[p]) * (double(a[c]) - b[c]) * (double(a[c]) - b[c]);
        weight += 3.0 * mask[p];
    }
    return weight > 0.0 ? std::sqrt(s / weight) : 0.0;
}

} // namespace tandem
