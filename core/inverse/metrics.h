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

/// The RMSE of `a` against `b` (param_error: over the optimized parameters' elements).
double rmse(const std::vector<float>& a, const std::vector<float>& b);

/// The RMSE of image `a` against `b` (3 floats a pixel) where `mask` (1 float a pixel in [0, 1])
/// weighs each pixel as the loss does: sqrt(sum_p m_p |a_p - b_p|^2 / (3 sum_p m_p)); without a
/// mask, rmse() (image_error). A mask of zeros leaves nothing to measure: 0.
double image_rmse(const std::vector<float>& a, const std::vector<float>& b,
                  const std::vector<float>& mask);

/// Loss, parameter RMSE and image RMSE against iteration, as a PNG (core/io/plot.h).
void write_convergence_plot(const std::string& path, const std::vector<MetricsRow>& rows);

} // namespace tandem
