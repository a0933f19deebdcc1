// Convergence plots (core/io/plot.h): the curves land in the image in their palette colours, unusable
// points are skipped, and failures throw one-line errors naming the file without touching it.
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <unistd.h>

#include "core/io/image_io.h"
#include "core/io/plot.h"
#include "runtime/error.h"

using namespace tandem;
namespace fs = std::filesystem;

namespace {

const double k_nan = std::numeric_limits<double>::quiet_NaN();
const double k_inf = std::numeric_limits<double>::infinity();

// the first two palette colours, as sRGB bytes (core/io/plot.h)
const int k_blue[3] = {31, 119, 180}, k_orange[3] = {255, 127, 14};

/// A fresh folder for this run's plots, removed when the test program exits.
struct ScratchDir {
    fs::path dir = fs::temp_directory_path() / ("tandem-plot-test-" + std::to_string(getpid()));
    ScratchDir() { fs::create_directories(dir); }
    ~ScratchDir() {
        std::error_code ec;
        fs::remove_all(dir, ec);
    }
};

std::string scratch(const std::string& name) {
    static const ScratchDir dir;
    return (dir.dir / name).string();
}

/// An image read back as sRGB bytes.
struct Picture {
    int width = 0, height = 0;
    std::vector<float> rgb;
    explicit Picture(const std::string& path) { rgb = read_image(path, &width, &height, false); }
    bool is(std::size_t pixel, const int c[3]) const {
        for (int k = 0; k < 3; ++k)
            if (std::abs(rgb[pixel * 3 + k] * 255 - c[k]) > 1.5f) return false;
        return true;
    }
    /// How many pixels have colour `c`, and the leftmost and rightmost column holding one.
    std::size_t count(const int c[3], int* x_min = nullptr, int* x_max = nullptr) const {
        std::size_t n = 0;
        int lo = width, hi = -1;
        for (std::size_t i = 0; i < std::size_t(width) * height; ++i)
            if (is(i, c)) {
                ++n;
                lo = std::min(lo, int(i % width));
                hi = std::max(hi, int(i % width));
            }
        if (x_min) *x_min = lo;
        if (x_max) *x_max = hi;
        return n;
    }
};

/// Files in the scratch folder named like write_image's temporaries (".name.tmpPID.ext").
int temporaries() {
    int n = 0;
    for (const auto& entry : fs::directory_iterator(fs::path(scratch("x")).parent_path()))
        n += entry.path().filename().string().find(".tmp") != std::string::npos;
    return n;
}

std::string file_text(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

/// 100 iterations of a decaying loss and a slower parameter error.
std::vector<PlotSeries> two_curves() {
    PlotSeries loss{"loss", {}, {}}, error{"parameter error", {}, {}};
    for (int i = 0; i < 100; ++i) {
        loss.x.push_back(i);
        loss.y.push_back(std::exp(-0.1 * i));
        error.x.push_back(i);
        error.y.push_back(0.5 * std::exp(-0.02 * i));
    }
    return {loss, error};
}

} // namespace

TEST_SUITE("plot") {
    TEST_CASE("plot: two curves in their colours on a white background") {
        const std::string path = scratch("two.png");
        PlotOptions options;
        options.title = "convergence";
        options.y_label = "value";
        write_plot(path, two_curves(), options);
        const Picture p(path);
        CHECK(p.width == 800);
        CHECK(p.height == 500);
        int lo = 0, hi = 0;
        CHECK(p.count(k_blue, &lo, &hi) > 200);
        CHECK(hi - lo > 400); // the curve runs across the plot
        CHECK(p.count(k_orange, &lo, &hi) > 200);
        CHECK(hi - lo > 400);
        const int white[3] = {255, 255, 255};
        CHECK(p.count(white) > std::size_t(0.8 * 800 * 500));
        CHECK(temporaries() == 0);
    }

    TEST_CASE("plot: other sizes, linear axes and formats") {
        const std::string path = scratch("small.exr");
        PlotOptions options;
        options.width = 300;
        options.height = 200;
        options.log_y = false;
        write_plot(path, {{"", {-3, 0, 7}, {-2.5, 1e3, 40}}}, options);
        int w, h;
        read_image(path, &w, &h);
        CHECK(w == 300);
        CHECK(h == 200);
    }

    TEST_CASE("plot: non-finite and (on log axes) non-positive points are skipped") {
        const std::string path = scratch("gaps.png");
        PlotSeries a{"a", {0, 1, 2, k_nan, 4, 5, 6, 7, 8, 9, 10},
                     {1, 0.5, k_nan, 0.2, k_inf, 0.1, 0, -1, 0.05, 0.02, 0.01}};
        PlotSeries b{"b", {0, 10, k_inf}, {1e-3, 1e-4, 1e-5}};
        write_plot(path, {a, b}, PlotOptions{});
        const Picture p(path);
        int lo = 0, hi = 0;
        CHECK(p.count(k_blue, &lo, &hi) > 100);
        CHECK(hi - lo > 400); // the skipped points neither broke the curve nor stretched the axes
        CHECK(p.count(k_orange, &lo, &hi) > 100);
        CHECK(hi - lo > 400);
    }

    TEST_CASE("plot: a single point, a constant curve and many decades") {
        const std::string path = scratch("edge.png");
        for (bool log_y : {true, false}) {
            PlotOptions options;
            options.log_y = log_y;
            write_plot(path, {{"one", {5}, {0.25}}}, options);
            CHECK(Picture(path).count(k_blue) >= 9); // a small square
            write_plot(path, {{"flat", {0, 1, 2}, {3, 3, 3}}, {"flat at 0", {0, 2}, {0, 0}}}, options);
            CHECK(Picture(path).count(k_blue) > 100);
            if (log_y)
                CHECK(Picture(path).count(k_orange) == 0); // 0 is skipped on log axes: no legend entry
            else
                CHECK(Picture(path).count(k_orange) > 100); // along the bottom of the frame
            write_plot(path, {{"wide", {0, 1, 2, 3}, {1e-300, 1e-100, 1, 1e300}}}, options);
            CHECK(Picture(path).count(k_blue) > 100);
        }
    }

    TEST_CASE("plot: nothing to plot throws naming the file") {
        const std::string path = scratch("nothing.png");
        CHECK_THROWS_WITH_AS(write_plot(path, {{"nan", {0, 1}, {k_nan, k_nan}}}, PlotOptions{}),
                             doctest::Contains((path + ": nothing to plot").c_str()), Error);
        CHECK_THROWS_WITH_AS(write_plot(path, {}, PlotOptions{}), doctest::Contains(path.c_str()), Error);
        CHECK_THROWS_WITH_AS(write_plot(path, {{"neg", {0, 1}, {-1, 0}}}, PlotOptions{}),
                             doctest::Contains(path.c_str()), Error);
        CHECK_THROWS_WITH_AS(write_plot(path, {{"short", {0, 1}, {1}}}, PlotOptions{}),
                             doctest::Contains((path + ": plot series 'short' has 2 x values").c_str()), Error);
        PlotOptions tiny;
        tiny.width = tiny.height = 8;
        CHECK_THROWS_WITH_AS(write_plot(path, two_curves(), tiny), doctest::Contains(path.c_str()), Error);
        CHECK_FALSE(fs::exists(path));
    }

    TEST_CASE("plot: an unwritable path throws naming the file") {
        const std::string path = scratch("no-such-folder/plot.png");
        CHECK_THROWS_WITH_AS(write_plot(path, two_curves(), PlotOptions{}), doctest::Contains(path.c_str()),
                             Error);
        const std::string bad = scratch("plot.not-an-image-format");
        CHECK_THROWS_WITH_AS(write_plot(bad, two_curves(), PlotOptions{}), doctest::Contains(bad.c_str()),
                             Error);
    }

    TEST_CASE("plot: a failed write leaves an existing file alone") {
        const std::string path = scratch("keep.png");
        write_plot(path, two_curves(), PlotOptions{});
        const std::string before = file_text(path);
        CHECK_THROWS_AS(write_plot(path, {{"nan", {0}, {k_nan}}}, PlotOptions{}), Error);
        CHECK(file_text(path) == before);
        // a write that fails in OIIO (an unknown format) leaves no temporary behind either
        const std::string other = scratch("keep.unknownformat");
        std::ofstream(other) << "keep me";
        CHECK_THROWS_AS(write_plot(other, two_curves(), PlotOptions{}), Error);
        CHECK(file_text(other) == "keep me");
        CHECK(temporaries() == 0);
    }
}
