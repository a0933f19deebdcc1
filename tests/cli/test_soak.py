#!/usr/bin/env python3
"""`tandem bench soak` works and nothing leaks in a short run.

    python3 tests/cli/test_soak.py TANDEM_BINARY [ITERATIONS]

ITERATIONS (default 600, a multiple of 20) at 16², 1 spp, sampled every 10 iterations (about 3 s
on 2 cores). Over the second half of the run (after the allocators and the first checkpoints have
settled), 31 samples:

- the live device buffers (count and bytes) are exactly the same at every sample;
- the heap (the bytes the host's allocator has handed out and not had back, counted to the byte)
  grows by at most HEAP_SLOPE_LIMIT = 1 KiB per iteration (least-squares slope). Without a leak
  it grew by 132-170 bytes per iteration in 13 runs (each fit's standard error about 14): the
  metrics rows the run keeps, 48 bytes each in a vector that doubles. The limit is 60 standard
  errors above that, and a 10 KiB-per-iteration leak (100 MB over 10^4 iterations) is 65 above
  the limit: it fails (tests/mutants/optimize-leak-10k.patch).
- resident memory grows by at most RSS_SLOPE_LIMIT = 4 KiB (a page) per iteration, for what the
  heap does not count (mappings, the OpenCL implementation's own). VmRSS counts whole 4 KiB pages:
  a reading off by one page at every sample moves the slope by at most
  4096 * sum|x - mean| / sum (x - mean)^2 = 40 bytes per iteration ("resolution" below), and 15
  runs measured 0 (12 runs), 17-20 (2) and 236 (1, an allocator's step of 52 KiB). The
  allocator's reuse of freed memory hides growth from VmRSS for a hundred iterations at a time,
  and its returns to the system show as drops of megabytes, so VmRSS cannot resolve 10 KiB per
  iteration here; the heap count can.

The sanitizer build passes 1,000: ASan's allocator keeps warming up its size-class caches for the
first few hundred iterations (measured: +1.4 MiB from 100 to 200, +0.4 MiB from 300 to 400, then
flat to 1000). There the heap is ASan's count: from 500 to 1000, 19 bytes per iteration and
resident memory 494 (one run); with the leak planted, 10,283 and 15,164 (with LeakSanitizer off;
on, it fails the run first). Standard library only.
"""

import json
import subprocess
import sys

SAMPLE_EVERY = 10
PAGE = 4096
HEAP_SLOPE_LIMIT = 1024.0  # bytes per iteration
RSS_SLOPE_LIMIT = 4096.0


def fit(xs, ys):
    """Least-squares slope of ys against xs, and the most readings off by one page can move it."""
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx
    return slope, PAGE * sum(abs(x - mx) for x in xs) / sxx


def main(binary, iterations):
    cmd = [binary, "bench", "soak", "--iterations", str(iterations), "--sample-every",
           str(SAMPLE_EVERY), "--res", "16", "--spp", "1", "--json"]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=3000)
    if run.returncode != 0:
        print(run.stdout + run.stderr)
        print(f"FAIL: exit {run.returncode}")
        return 1
    r = json.loads(run.stdout)
    samples = r["samples"]
    failures = []
    expected = list(range(SAMPLE_EVERY, iterations + 1, SAMPLE_EVERY))
    if [s["iteration"] for s in samples] != expected:
        failures.append(f"samples at {[s['iteration'] for s in samples]}, not {expected}")
    else:
        window = [s for s in samples if s["iteration"] >= iterations // 2]
        for s in samples:
            print(f"iteration {s['iteration']}: {s}")
        print(f"guards {r['guards']}, restir {r['restir']}, {r['seconds']:.2f} s")
        for key in ("live_buffers", "live_buffer_bytes"):
            if any(s[key] != window[0][key] for s in window) or window[0][key] <= 0:
                failures.append(f"{key}: {[s[key] for s in window]} from iteration "
                                f"{window[0]['iteration']}")
        xs = [s["iteration"] for s in window]
        for key, name, limit in (("heap_bytes", "heap", HEAP_SLOPE_LIMIT),
                                 ("rss_bytes", "RSS", RSS_SLOPE_LIMIT)):
            slope, resolution = fit(xs, [s[key] for s in window])
            print(f"{name} from iteration {xs[0]} to {xs[-1]}: {slope:.1f} bytes per iteration "
                  f"(limit {limit:.0f}" + (f", resolution {resolution:.1f}" if key == "rss_bytes"
                                           else "") +
                  f"); grew by {window[-1][key] - window[0][key]:.0f} bytes")
            if slope > limit:
                failures.append(f"{name} grows by {slope:.0f} bytes per iteration over the last "
                                f"{len(window)} samples (limit {limit:.0f})")
        if not all(s["seconds_per_iteration"] > 0 for s in samples):
            failures.append("a sample has no time per iteration")
    for key in ("rss_bytes", "heap_bytes", "live_buffers", "live_buffer_bytes",
                "seconds_per_iteration"):
        if key not in r["slopes"] or "slope_per_iteration" not in r["slopes"][key]:
            failures.append(f"no slope for {key}")
    for f in failures:
        print("FAIL: " + f)
    return 1 if failures else 0


if __name__ == "__main__":
    if len(sys.argv) not in (2, 3):
        sys.exit(__doc__)
    count = int(sys.argv[2]) if len(sys.argv) == 3 else 600
    if count < 200 or count % (2 * SAMPLE_EVERY):
        sys.exit(f"ITERATIONS must be a multiple of {2 * SAMPLE_EVERY}, at least 200 (got {count})")
    sys.exit(main(sys.argv[1], count))
