// Line plots drawn into an OIIO ImageBuf (sRGB values), then written through write_image.
#include "core/io/plot.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <optional>

#include <OpenImageIO/imagebufalgo.h>

#include "core/io/image_io.h"
#include "runtime/error.h"

namespace tandem {

namespace IBA = OIIO::ImageBufAlgo;

namespace {

using Colour = std::array<float, 3>;

// matplotlib's "tab10", in sRGB
const Colour k_palette[] = {
    {31 / 255.f, 119 / 255.f, 180 / 255.f}, {255 / 255.f, 127 / 255.f, 14 / 255.f},
    {44 / 255.f, 160 / 255.f, 44 / 255.f},  {214 / 255.f, 39 / 255.f, 40 / 255.f},
    {148 / 255.f, 103 / 255.f, 189 / 255.f}, {140 / 255.f, 86 / 255.f, 75 / 255.f},
    {227 / 255.f, 119 / 255.f, 194 / 255.f}, {127 / 255.f, 127 / 255.f, 127 / 255.f},
    {188 / 255.f, 189 / 255.f, 34 / 255.f},  {23 / 255.f, 190 / 255.f, 207 / 255.f}};
const Colour k_white{1, 1, 1}, k_black{0, 0, 0}, k_grid{0.88f, 0.88f, 0.88f},
    k_frame{0.6f, 0.6f, 0.6f};

/// The first font OIIO can load, or none. OIIO's own default (DroidSans) is not packaged by
/// Debian, hence the fallbacks, which OIIO finds by name under /usr/share/fonts and the like.
const std::optional<std::string>& plot_font() {
    static const std::optional<std::string> font = []() -> std::optional<std::string> {
        for (const char* name : {"", "DejaVuSans", "LiberationSans-Regular", "FreeSans"})
            if (IBA::text_size("0", 12, name).defined()) return std::string(name);
        return std::nullopt;
    }();
    return font;
}

/// An axis: its range (log10 of the values on log axes), the labelled tick positions and the
/// unlabelled minor ones (2..9 within each decade when a log axis spans few decades).
struct Axis {
    double lo = 0, hi = 1;
    bool log = false;
    std::vector<double> major, minor;
    int digits = 6; // %g precision of linear tick labels

    std::string label(double v) const {
        char s[32];
        if (log) {
            const long d = std::lround(v);
            std::snprintf(s, sizeof s, d == 0 ? "1" : d == 1 ? "10" : "1e%ld", d);
        } else {
            std::snprintf(s, sizeof s, "%.*g", digits, v + 0.0); // + 0.0 turns -0 into 0
        }
        return s;
    }
};

/// 1, 2 or 5 times a power of ten, at least `rough`.
double nice_step(double rough) {
    const double p = std::pow(10.0, std::floor(std::log10(rough)));
    for (double m : {1.0, 2.0, 5.0})
        if (m * p >= rough) return m * p;
    return 10 * p;
}

/// Linear axis over [lo, hi], widened to whole ticks; a degenerate range is widened by 10% of its
/// value (or by 1 around 0).
Axis linear_axis(double lo, double hi) {
    Axis a;
    if (!(hi - lo > 1e-9 * std::max(std::abs(lo), std::abs(hi)))) {
        const double pad = lo != 0 ? 0.1 * std::abs(lo) : 1.0;
        lo -= pad;
        hi += pad;
    }
    const double step = nice_step((hi - lo) / 5);
    a.lo = std::floor(lo / step) * step;
    a.hi = std::ceil(hi / step) * step;
    for (int i = 0; i <= 20 && a.lo + i * step <= a.hi + 1e-9 * step; ++i)
        a.major.push_back(std::round(a.lo / step + i) * step);
    const double big = std::max(std::abs(a.lo), std::abs(a.hi));
    a.digits = std::clamp(int(std::ceil(std::log10(big / step))) + 1, 6, 15);
    return a;
}

/// Log axis over decades [lo, hi] (already log10), widened to whole decades; at most ~8 labelled
/// decades, so long spans tick every 2, 5, 10, 20, ... decades.
Axis log_axis(double lo, double hi) {
    Axis a;
    a.log = true;
    lo = std::floor(lo);
    hi = std::ceil(hi);
    if (hi == lo) --lo, ++hi;
    const double every = std::max(1.0, nice_step((hi - lo) / 8));
    a.lo = std::floor(lo / every) * every;
    a.hi = std::ceil(hi / every) * every;
    for (double d = a.lo; d <= a.hi; d += every) {
        a.major.push_back(d);
        if (every == 1 && a.hi - a.lo <= 6 && d < a.hi)
            for (int m = 2; m <= 9; ++m) a.minor.push_back(d + std::log10(m));
    }
    return a;
}

/// Text drawing that degrades to nothing: without a font, or when OIIO fails, no text is drawn
/// and every text is 0 x 0.
struct Text {
    OIIO::ImageBuf& buf;
    std::optional<std::string> font;
    int size;

    int width(const std::string& s) const {
        const OIIO::ROI r = font ? IBA::text_size(s, size, *font) : OIIO::ROI();
        return r.defined() ? r.width() : 0;
    }
    void draw(int x, int y, const std::string& s, IBA::TextAlignX ax, IBA::TextAlignY ay,
              const Colour& c = k_black) const {
        if (!font || s.empty()) return;
        if (!IBA::render_text(buf, x, y, s, size, *font, c, ax, ay)) buf.geterror(); // clears it
    }
    /// `s` turned a quarter left (reading upwards), centred on (x, y).
    void draw_vertical(int x, int y, const std::string& s) const {
        const OIIO::ROI r = font && !s.empty() ? IBA::text_size(s, size, *font) : OIIO::ROI();
        if (!r.defined()) return;
        OIIO::ImageBuf flat(OIIO::ImageSpec(r.width() + 2, r.height() + 2, 3, OIIO::TypeDesc::FLOAT));
        IBA::fill(flat, k_white);
        if (!IBA::render_text(flat, 1 - r.xbegin, 1 - r.ybegin, s, size, *font, k_black)) return;
        const OIIO::ImageBuf up = IBA::rotate270(flat);
        IBA::paste(buf, x - up.spec().width / 2, y - up.spec().height / 2, 0, 0, up);
    }
};

} // namespace

void write_plot(const std::string& path, const std::vector<PlotSeries>& series,
                const PlotOptions& options) {
    // The usable points of each series, y in log10 on log axes, and their bounds.
    std::vector<std::vector<std::pair<double, double>>> points(series.size());
    double xlo = INFINITY, xhi = -INFINITY, ylo = INFINITY, yhi = -INFINITY;
    for (std::size_t s = 0; s < series.size(); ++s) {
        const PlotSeries& ps = series[s];
        if (ps.x.size() != ps.y.size())
            throw Error(path + ": plot series '" + ps.label + "' has " + std::to_string(ps.x.size()) +
                        " x values but " + std::to_string(ps.y.size()) + " y values");
        for (std::size_t i = 0; i < ps.x.size(); ++i) {
            // log10 of 0 is -inf, of a negative number NaN
            const double x = ps.x[i], y = options.log_y ? std::log10(ps.y[i]) : ps.y[i];
            if (!std::isfinite(x) || !std::isfinite(y)) continue;
            points[s].emplace_back(x, y);
            xlo = std::min(xlo, x), xhi = std::max(xhi, x), ylo = std::min(ylo, y), yhi = std::max(yhi, y);
        }
    }
    if (!(xlo <= xhi))
        throw Error(path + ": nothing to plot (no finite" + (options.log_y ? ", positive" : "") +
                    " points)");
    const Axis ax = linear_axis(xlo, xhi), ay = options.log_y ? log_axis(ylo, yhi) : linear_axis(ylo, yhi);

    const int w = options.width, h = options.height;
    if (w < 1 || h < 1 || w > 16384 || h > 16384)
        throw Error(path + ": bad plot size " + std::to_string(w) + "x" + std::to_string(h));
    OIIO::ImageBuf buf(OIIO::ImageSpec(w, h, 3, OIIO::TypeDesc::FLOAT));
    IBA::fill(buf, k_white);
    const Text text{buf, plot_font(), std::max(10, std::min(w, h) / 40)};
    const int fs = text.font ? text.size : 0, tick = 5;

    // Margins around the plot area [x0, x1] x [y0, y1] leave room for the text that is drawn.
    int label_w = 0;
    for (double v : ay.major) label_w = std::max(label_w, text.width(ay.label(v)));
    const int x0 = 10 + (fs ? tick + 4 + label_w + (options.y_label.empty() ? 0 : fs + 10) : 0);
    const int x1 = w - 1 - std::max(20, fs ? text.width(ax.label(ax.hi)) / 2 + 4 : 0);
    const int y0 = 10 + (fs && !options.title.empty() ? 2 * fs : fs / 2);
    const int y1 = h - 1 - (fs ? tick + 2 * fs + (options.x_label.empty() ? 0 : fs + 8) : 10);
    if (x1 - x0 < 20 || y1 - y0 < 20)
        throw Error(path + ": plot size " + std::to_string(w) + "x" + std::to_string(h) +
                    " leaves no room to plot");
    // Pixel of an axis value; clamped (also against NaN from overflowing ranges).
    auto pixel = [](const Axis& a, double v, int p0, int p1) {
        double t = (v - a.lo) / (a.hi - a.lo);
        t = t >= 0 ? std::min(t, 1.0) : 0.0;
        return int(std::lround(p0 + t * (p1 - p0)));
    };
    // The axis ranges sit a few pixels inside the frame, so curves along them stay visible.
    const int inset = 4;
    auto px = [&](double v) { return pixel(ax, v, x0 + inset, x1 - inset); };
    auto py = [&](double v) { return pixel(ay, v, y1 - inset, y0 + inset); };

    // Grid, ticks and their labels, the frame; then the curves.
    using AX = IBA::TextAlignX;
    using AY = IBA::TextAlignY;
    for (double v : ax.major) {
        const int x = px(v);
        IBA::render_line(buf, x, y0, x, y1, k_grid);
        IBA::render_line(buf, x, y1, x, y1 + tick, k_black);
        text.draw(x, y1 + tick + 2, ax.label(v), AX::Center, AY::Top);
    }
    for (double v : ay.major) {
        const int y = py(v);
        IBA::render_line(buf, x0, y, x1, y, k_grid);
        IBA::render_line(buf, x0 - tick, y, x0, y, k_black);
        text.draw(x0 - tick - 3, y, ay.label(v), AX::Right, AY::Center);
    }
    for (double v : ay.minor) IBA::render_line(buf, x0 - tick / 2, py(v), x0, py(v), k_black);
    IBA::render_box(buf, x0, y0, x1, y1, k_black);
    for (std::size_t s = 0; s < series.size(); ++s) {
        const Colour& c = k_palette[s % std::size(k_palette)];
        const auto& p = points[s];
        if (p.size() == 1)
            IBA::render_box(buf, px(p[0].first) - 2, py(p[0].second) - 2, px(p[0].first) + 2,
                            py(p[0].second) + 2, c, true);
        for (std::size_t i = 1; i < p.size(); ++i)
            for (int d : {0, 1}) // two pixels thick
                IBA::render_line(buf, px(p[i - 1].first), py(p[i - 1].second) + d, px(p[i].first),
                                 py(p[i].second) + d, c);
    }

    // Title, axis labels and the legend (top right, inside the plot area).
    text.draw((x0 + x1) / 2, y0 - fs / 2 - 2, options.title, AX::Center, AY::Bottom);
    text.draw((x0 + x1) / 2, h - 1 - 6, options.x_label, AX::Center, AY::Bottom);
    text.draw_vertical(10 + fs / 2, (y0 + y1) / 2, options.y_label);
    std::vector<std::size_t> legend;
    int legend_w = 0;
    for (std::size_t s = 0; s < series.size(); ++s)
        if (fs && !series[s].label.empty() && !points[s].empty()) {
            legend.push_back(s);
            legend_w = std::max(legend_w, text.width(series[s].label));
        }
    if (!legend.empty()) {
        const int row = fs + 6, lx1 = x1 - 8, lx0 = lx1 - (8 + 24 + 6 + legend_w + 8);
        const int ly0 = y0 + 8, ly1 = ly0 + 4 + row * int(legend.size()) + 2;
        IBA::render_box(buf, lx0, ly0, lx1, ly1, k_white, true);
        IBA::render_box(buf, lx0, ly0, lx1, ly1, k_frame);
        for (std::size_t i = 0; i < legend.size(); ++i) {
            const int y = ly0 + 4 + row * int(i) + row / 2;
            const Colour& c = k_palette[legend[i] % std::size(k_palette)];
            IBA::render_box(buf, lx0 + 8, y - 1, lx0 + 8 + 24, y, c, true);
            text.draw(lx0 + 8 + 24 + 6, y, series[legend[i]].label, AX::Left, AY::Center);
        }
    }

    // The buffer holds sRGB values; write_image takes linear ones (and encodes 8-bit formats
    // back to sRGB, exactly).
    std::vector<float> rgb(std::size_t(w) * h * 3);
    buf.get_pixels(OIIO::ROI(0, w, 0, h, 0, 1, 0, 3), OIIO::TypeDesc::FLOAT, rgb.data());
    for (float& v : rgb) v = v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
    write_image(path, w, h, rgb);
}

} // namespace tandem
