// The per-iteration metrics of `tandem optimize`: rows, their CSV, and the convergence plot.
#pragma once

#include <string>
#include <vector>

namespace tandem {

struct MetricsRow {
    int iteration = 0;
    double seconds = 0.0;
    float loss = 0.0f;
    double param_error = -1.0, image_error = -1.0, alpha_mean = -1.0; ///< -1: not measured
    /// A row of a run resumed with --force over changed inputs (core/inverse/checkpoint.h): it
    /// and every row after it belong to a mixture of two problems.
    bool inputs_changed = false;
};

/// "iteration,seconds,loss,param_error,image_error,alpha_mean,inputs_changed" and one line per
/// row (blank where not measured; inputs_changed 1 or blank).
std::string metrics_csv(const std::vector<MetricsRow>& rows);

/// One row of metrics_csv(), with its line break.
std::string metrics_csv_row(const MetricsRow& row);

/// Loss, parameter RMSE and image RMSE against iteration, as a PNG (core/io/plot.h).
void write_convergence_plot(const std::string& path, const std::vector<MetricsRow>& rows);

} // namespace tandem
