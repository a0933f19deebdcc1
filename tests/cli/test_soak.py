#!/usr/bin/env python3
"""`tandem bench soak` works and nothing leaks in a short run.

    python3 tests/cli/test_soak.py TANDEM_BINARY

200 iterations at 16², 1 spp (a few seconds): the JSON has a sample at iterations 100 and 200,
the live device buffers (count and bytes) are exactly the same at both, and the resident memory
grows by at most 1 MiB between them. Standard library only.
"""

import json
import subprocess
import sys

RSS_TOLERANCE = 1 << 20


def main(binary):
    cmd = [binary, "bench", "soak", "--iterations", "200", "--res", "16", "--spp", "1", "--json"]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    if run.returncode != 0:
        print(run.stdout + run.stderr)
        print(f"FAIL: exit {run.returncode}")
        return 1
    r = json.loads(run.stdout)
    samples = r["samples"]
    failures = []
    if [s["iteration"] for s in samples] != [100, 200]:
        failures.append(f"samples at {[s['iteration'] for s in samples]}, not [100, 200]")
    else:
        a, b = samples
        print(f"iteration 100: {a}\niteration 200: {b}\nguards {r['guards']}, "
              f"restir {r['restir']}, {r['seconds']:.2f} s")
        for key in ("live_buffers", "live_buffer_bytes"):
            if a[key] != b[key] or a[key] <= 0:
                failures.append(f"{key}: {a[key]} at iteration 100, {b[key]} at 200")
        if b["rss_bytes"] - a["rss_bytes"] > RSS_TOLERANCE:
            failures.append(f"RSS grew by {b['rss_bytes'] - a['rss_bytes']:.0f} bytes "
                            f"(tolerance {RSS_TOLERANCE})")
        if not all(s["seconds_per_iteration"] > 0 for s in samples):
            failures.append("a sample has no time per iteration")
    for key in ("rss_bytes", "live_buffers", "live_buffer_bytes", "seconds_per_iteration"):
        if key not in r["slopes"] or "slope_per_iteration" not in r["slopes"][key]:
            failures.append(f"no slope for {key}")
    for f in failures:
        print("FAIL: " + f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
