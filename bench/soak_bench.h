// `tandem bench soak`: a long `tandem optimize` run (PRB + CV-PS + Adam, ReSTIR when the scene
// supports it, metrics, checkpoints and images as the command writes them) sampled every
// `sample_every` iterations: host resident memory (VmRSS), the bytes the host's allocator has
// handed out and not had back (heap_bytes), live device buffers (count and bytes,
// runtime/buffer_count.h) and the mean wall time per iteration over the last window. Each series
// gets a least-squares slope against iteration with its standard error; flat means within 3
// standard errors of zero (the allocation counts: exactly constant).
#pragma once

#include "runtime/tuning.h"

#include <cstddef>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace tandem {

struct SoakBenchOptions {
    std::string scene = TANDEM_BENCH_SCENE_DIR "/gallery-lights.xml";
    std::string param = "painting.reflectance"; ///< optimized from a flat 0.5
    int iterations = 10000;
    int sample_every = 100;
    int res = 32;              ///< square film
    int spp = 4;               ///< primal and adjoint
    int checkpoint_every = 100; ///< checkpoint, re-render and images every K iterations
    std::string restir = "auto"; ///< "auto" (when the scene supports it), "on" or "off"
    std::string device;
    Tuning tuning; ///< the switches, as the entry point read them (runtime/tuning.h)
    bool progress = false;
};

struct SoakSample {
    int iteration = 0;
    double rss_bytes = 0;             ///< VmRSS
    double heap_bytes = 0;            ///< heap_bytes(): allocated and not freed
    std::size_t live_buffers = 0;     ///< Buffer objects holding an allocation
    std::size_t live_buffer_bytes = 0;
    double seconds_per_iteration = 0; ///< mean wall time over the iterations since the last sample
};

/// A least-squares line y = a + slope * iteration over the samples.
struct SoakSlope {
    double slope = 0, stderr_ = 0, mean = 0;
    double drift = 0;  ///< slope times the sampled span of iterations, over the mean
    bool flat = false; ///< |slope| <= 3 stderr (exactly constant when stderr is 0)
    nlohmann::json to_json() const;
};

struct SoakBenchResult {
    std::string scene, param, device, restir;
    int res = 0, spp = 0, iterations = 0, sample_every = 0;
    double seconds = 0; ///< wall time of the whole run
    std::uint64_t guards = 0;
    float final_loss = 0;
    std::vector<SoakSample> samples;
    SoakSlope rss, heap, buffers, buffer_bytes, time;
    nlohmann::json to_json() const;
    std::string to_table() const;
    std::string samples_csv() const;
};

/// Fits y against x by least squares.
SoakSlope fit_slope(const std::vector<double>& x, const std::vector<double>& y);

/// Host resident memory of this process in bytes (VmRSS of /proc/self/status; 0 if unreadable).
double resident_bytes();

/// Bytes of the host heap allocated and not yet freed, to the byte: glibc's mallinfo2 (in use in
/// every arena, and mmapped), or under AddressSanitizer its allocator's count; 0 elsewhere.
/// Unlike VmRSS it does not move when the allocator reuses or returns freed memory.
double heap_bytes();

SoakBenchResult run_soak_bench(const SoakBenchOptions& options);

} // namespace tandem
