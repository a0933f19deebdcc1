// A long optimization run, sampled: memory, device allocations and time per iteration.
#include "bench/soak_bench.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <unistd.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif
#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define TANDEM_ASAN 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define TANDEM_ASAN 1
#endif
#if defined(TANDEM_ASAN)
// The sanitizer runtime's count of the bytes allocated and not freed
// (<sanitizer/allocator_interface.h>, which GCC 12 does not install).
extern "C" std::size_t __sanitizer_get_current_allocated_bytes();
#endif

#include "core/inverse/optimize.h"
#include "core/inverse/restir.h"
#include "runtime/buffer_count.h"
#include "runtime/error.h"

namespace tandem {

namespace fs = std::filesystem;

double resident_bytes() {
    std::ifstream in("/proc/self/status");
    std::string line;
    while (std::getline(in, line))
        if (line.rfind("VmRSS:", 0) == 0) return std::stod(line.substr(6)) * 1024.0; // kB
    return 0.0;
}

double heap_bytes() {
#if defined(TANDEM_ASAN)
    return double(__sanitizer_get_current_allocated_bytes());
#elif defined(__GLIBC__)
    const struct mallinfo2 m = mallinfo2();
    return double(m.uordblks) + double(m.hblkhd);
#else
    return 0.0;
#endif
}

SoakSlope fit_slope(const std::vector<double>& x, const std::vector<double>& y) {
    SoakSlope s;
    const std::size_t n = x.size();
    if (n == 0) return s;
    double mx = 0, my = 0;
    for (std::size_t i = 0; i < n; ++i)
        mx += x[i] / double(n), my += y[i] / double(n);
    double sxx = 0, sxy = 0;
    for (std::size_t i = 0; i < n; ++i)
        sxx += (x[i] - mx) * (x[i] - mx), sxy += (x[i] - mx) * (y[i] - my);
    s.mean = my;
    s.slope = sxx > 0 ? sxy / sxx : 0.0;
    double ssr = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const double r = y[i] - my - s.slope * (x[i] - mx);
        ssr += r * r;
    }
    s.stderr_ = n > 2 && sxx > 0 ? std::sqrt(ssr / double(n - 2) / sxx) : 0.0;
    s.drift = my != 0 ? s.slope * (x.back() - x.front()) / my : 0.0;
    s.flat = s.stderr_ > 0 ? std::fabs(s.slope) <= 3.0 * s.stderr_ : s.slope == 0.0;
    return s;
}

nlohmann::json SoakSlope::to_json() const {
    return {{"slope_per_iteration", slope}, {"stderr", stderr_}, {"mean", mean},
            {"drift_over_run", drift},      {"flat", flat}};
}

SoakBenchResult run_soak_bench(const SoakBenchOptions& o) {
    // Iteration 1 (kernel builds, first allocations) only starts the first window, so a sample
    // falls on every multiple of --sample-every after it. A slope needs two of them (its
    // standard error, and so the verdict "flat", three: with two, only a slope of exactly 0
    // counts as flat).
    const int fewest = std::max(2 * o.sample_every, o.sample_every == 1 ? 3 : 2);
    if (o.sample_every < 1 || o.iterations < fewest)
        throw Error("bench soak: --iterations must be at least " + std::to_string(fewest) +
                    " for --sample-every " + std::to_string(o.sample_every) +
                    " (two samples after the first iteration)");
    Context ctx = Context::create(o.device, o.tuning);
    const KernelLibrary& lib = KernelLibrary::from_tuning(o.tuning);
    const std::vector<std::pair<std::string, std::string>> defines = {
        {"res", std::to_string(o.res)}};
    const RenderScene scene = build_render_scene(load_scene(o.scene, defines));
    scene.params.find(o.param); // an unknown name fails here, before any device work
    OptimizeConfig c;
    c.path = "bench soak";
    c.scene = c.target_scene = o.scene;
    c.defines = c.target_defines = defines;
    c.target_spp = 64;
    OptimizedParam p;
    p.name = o.param;
    p.lr = 0.02f;
    p.init = {0.5f};
    c.params = {p};
    c.iterations = o.iterations;
    c.spp = c.spp_grad = o.spp;
    c.loss = "l2";
    c.checkpoint_every = o.checkpoint_every;
    c.image_error_spp = 16;
    c.cv = "ps";
    const std::string why_not = restir_unsupported(scene);
    if (o.restir == "on" && !why_not.empty()) throw Error(o.scene + ": ReSTIR: " + why_not);
    const bool restir = o.restir == "on" || (o.restir == "auto" && why_not.empty());
    if (restir) c.restir = RestirConfig{};

    SoakBenchResult result;
    result.scene = o.scene;
    result.param = o.param;
    result.device = ctx.device().name;
    result.restir = restir ? "on" : "off (" + (why_not.empty() ? "--restir off" : why_not) + ")";
    result.res = o.res;
    result.spp = o.spp;
    result.iterations = o.iterations;
    result.sample_every = o.sample_every;

    OptimizeOptions oo;
    oo.out_dir =
        (fs::temp_directory_path() / ("tandem-soak-" + std::to_string(getpid()))).string();
    fs::remove_all(oo.out_dir);
    using clock = std::chrono::steady_clock;
    clock::time_point last; // the previous sample (or the first iteration's end)
    int last_it = 0;
    oo.progress = [&](int it, int total, float) {
        const clock::time_point now = clock::now();
        if (it == 1) last = now, last_it = 1; // the window of the first sample starts here
        if (it == last_it || it % o.sample_every != 0) return;
        SoakSample s;
        s.iteration = it;
        s.rss_bytes = resident_bytes();
        s.heap_bytes = heap_bytes();
        s.live_buffers = live_buffers();
        s.live_buffer_bytes = live_buffer_bytes();
        s.seconds_per_iteration =
            std::chrono::duration<double>(now - last).count() / double(it - last_it);
        last = now, last_it = it;
        result.samples.push_back(s);
        if (o.progress)
            std::cerr << "\rbench soak: " << it << "/" << total << ", RSS "
                      << std::setprecision(4) << s.rss_bytes / 1048576.0 << " MiB, "
                      << s.live_buffers << " buffers, " << s.seconds_per_iteration * 1e3
                      << " ms/iteration   " << std::flush;
    };
    const auto t0 = clock::now();
    OptimizeSummary summary;
    try {
        summary = run_optimization(ctx, lib, c, oo);
    } catch (...) {
        fs::remove_all(oo.out_dir);
        throw;
    }
    result.seconds = std::chrono::duration<double>(clock::now() - t0).count();
    if (o.progress) std::cerr << "\n";
    fs::remove_all(oo.out_dir);
    result.guards = summary.guards;
    result.final_loss = summary.final_loss;

    std::vector<double> x, rss, heap, n, bytes, t;
    for (const SoakSample& s : result.samples) {
        x.push_back(s.iteration);
        rss.push_back(s.rss_bytes);
        heap.push_back(s.heap_bytes);
        n.push_back(double(s.live_buffers));
        bytes.push_back(double(s.live_buffer_bytes));
        t.push_back(s.seconds_per_iteration);
    }
    result.rss = fit_slope(x, rss);
    result.heap = fit_slope(x, heap);
    result.buffers = fit_slope(x, n);
    result.buffer_bytes = fit_slope(x, bytes);
    result.time = fit_slope(x, t);
    return result;
}

nlohmann::json SoakBenchResult::to_json() const {
    nlohmann::json s = nlohmann::json::array();
    for (const SoakSample& v : samples)
        s.push_back({{"iteration", v.iteration},
                     {"rss_bytes", v.rss_bytes},
                     {"heap_bytes", v.heap_bytes},
                     {"live_buffers", v.live_buffers},
                     {"live_buffer_bytes", v.live_buffer_bytes},
                     {"seconds_per_iteration", v.seconds_per_iteration}});
    return {{"scene", scene},
            {"param", param},
            {"device", device},
            {"restir", restir},
            {"res", res},
            {"spp", spp},
            {"iterations", iterations},
            {"sample_every", sample_every},
            {"seconds", seconds},
            {"guards", guards},
            {"final_loss", final_loss},
            {"slopes",
             {{"rss_bytes", rss.to_json()},
              {"heap_bytes", heap.to_json()},
              {"live_buffers", buffers.to_json()},
              {"live_buffer_bytes", buffer_bytes.to_json()},
              {"seconds_per_iteration", time.to_json()}}},
            {"samples", s}};
}

std::string SoakBenchResult::samples_csv() const {
    std::ostringstream s;
    s << "iteration,rss_bytes,heap_bytes,live_buffers,live_buffer_bytes,seconds_per_iteration\n"
      << std::setprecision(9);
    for (const SoakSample& v : samples)
        s << v.iteration << "," << v.rss_bytes << "," << v.heap_bytes << "," << v.live_buffers
          << "," << v.live_buffer_bytes << "," << v.seconds_per_iteration << "\n";
    return s.str();
}

std::string SoakBenchResult::to_table() const {
    std::ostringstream s;
    s << "scene " << scene << " at " << res << "², parameter " << param << ", " << spp
      << " spp, PRB + CV-PS + Adam, ReSTIR " << restir << ", device " << device << "\n"
      << iterations << " iterations in " << std::fixed << std::setprecision(1) << seconds
      << " s, sampled every " << sample_every << "; " << guards << " guards, final loss "
      << std::scientific << std::setprecision(3) << final_loss << "\n";
    s << "| series | first | last | mean | slope / iteration | std. error | drift over run | "
         "flat |\n|---|---|---|---|---|---|---|---|\n";
    const auto row = [&](const char* name, const SoakSlope& f, double first, double last) {
        s << "| " << name << " | " << std::setprecision(4) << std::defaultfloat << first << " | "
          << last << " | " << f.mean << " | " << std::setprecision(3) << f.slope << " | "
          << f.stderr_ << " | " << std::fixed << std::setprecision(3) << 100.0 * f.drift
          << " % | " << (f.flat ? "yes" : "no") << " |\n";
    };
    if (!samples.empty()) {
        const SoakSample &a = samples.front(), &b = samples.back();
        row("RSS (bytes)", rss, a.rss_bytes, b.rss_bytes);
        row("heap (bytes)", heap, a.heap_bytes, b.heap_bytes);
        row("live buffers", buffers, double(a.live_buffers), double(b.live_buffers));
        row("live buffer bytes", buffer_bytes, double(a.live_buffer_bytes),
            double(b.live_buffer_bytes));
        row("s / iteration", time, a.seconds_per_iteration, b.seconds_per_iteration);
    }
    return s.str();
}

} // namespace tandem
