// Line plots (convergence curves of `tandem optimize`) drawn with OpenImageIO, no plotting library.
#pragma once

#include <string>
#include <vector>

namespace tandem {

/// One curve. Series are coloured in order from the "tab10" palette: blue (31, 119, 180), orange
/// (255, 127, 14), green (44, 160, 44), red (214, 39, 40), ... (sRGB bytes), repeating after ten.
struct PlotSeries {
    std::string label;        ///< legend text, e.g. "loss"; an empty label gets no legend entry
    std::vector<double> x, y; ///< same length; non-finite or (on log axes) non-positive points are skipped
};

struct PlotOptions {
    int width = 800, height = 500;
    std::string title, x_label = "iteration", y_label;
    bool log_y = true; ///< decades on the y axis
};

/// Draws the series as polylines (a lone point as a square) on a white background with a frame,
/// grid lines and tick marks (decades on log axes) and, when a TrueType font is found (OIIO's
/// default, else DejaVu Sans, Liberation Sans or FreeSans), the title, axis labels, tick labels
/// and a legend; without a font the plot is drawn without text. Writes `path` through
/// write_image (core/io/image_io.h): PNG or any format OIIO knows by extension, atomically. Throws
/// Error naming `path` when there is nothing to plot (no usable point), when x and y of a series
/// differ in length, when the size leaves no room to plot, or when the file cannot be written.
void write_plot(const std::string& path, const std::vector<PlotSeries>& series,
                const PlotOptions& options);

} // namespace tandem
