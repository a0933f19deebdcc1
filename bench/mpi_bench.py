#!/usr/bin/env python3
"""Several processes (`mpirun -np N tandem optimize`): what the exchanges between ranks cost, and
what two ranks give on one machine.

1. Strong scaling on this machine: the globe job (scenes/globe-recover.json, eight 96x96 views,
   every view every iteration, CV-PS, 4 + 4 spp) for --iterations iterations as
     - one rank with --threads PoCL threads (POCL_MAX_PTHREAD_COUNT),
     - one rank with one thread,
     - --threads ranks with one thread each (mpirun --oversubscribe -x POCL_MAX_PTHREAD_COUNT=1),
   alternating over --rounds rounds. Reported: seconds per iteration (metrics.csv's last
   "seconds" over the iterations; the median over rounds), the speed-up of the ranks over one
   rank with as many threads, and over one thread; and whether every mode ended on the same
   parameters (params.json, byte for byte).
2. The exchanges at 2 ranks, per texture size (--textures: the globe painted with a W x W/2
   texture, -D texture=...; the 128 x 64 original first): rank 0's exchange seconds per
   iteration (`tandem optimize --json`: exchange_seconds, after a barrier that separates the
   wait for the other rank, exchange_wait_seconds), the bytes exchanged per iteration, and the
   exchange's share of the iteration time.
3. A projection to 8-64 GPUs (the assumptions are arguments, printed with the table): an
   iteration of V views on N GPUs costs ceil(V / N) view times (--gpu-view-ms: one view's primal
   and adjoint on one GPU) plus the all-reduce of the gradient's 12 bytes per texel channel
   (3 words: docs/cli.md): its download and upload over PCIe (--pcie-gbs), the merge on the host
   at the merge rate measured in part 2 (bytes over exchange seconds at the largest texture, a
   lower bound of the rate: that time also holds the copies), and a ring all-reduce over the
   network, 2 (N - 1) / N of the bytes at --net-gbs plus 2 (N - 1) latencies (--latency-us).

    python3 bench/mpi_bench.py [--tandem build/tandem] [--mpirun mpirun] [--iterations 24]
        [--rounds 3] [--textures 128 512 1024] [--out FILE.md]

Needs Open MPI's mpirun and a tandem built with MPI (TANDEM_MPI); numpy and the Python module
for the larger textures.
"""

import argparse
import csv
import json
import math
import os
import pathlib
import platform
import statistics
import subprocess
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]
SCENES = ROOT / "scenes"
MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1"}


def config(tmp, name, iterations, texture=None, views=8):
    c = json.loads((SCENES / "globe-recover.json").read_text())
    c["scene"] = str(SCENES / c["scene"])
    c["target"]["scene"] = str(SCENES / c["target"]["scene"])
    c["iterations"] = iterations
    c["checkpoint_every"] = iterations
    c["image_error_spp"] = 1
    if texture:  # the same globe, painted with a larger image, for the scene and its target
        c["defines"]["texture"] = str(texture)
        c["target"]["defines"]["texture"] = str(texture)
    path = tmp / f"{name}.json"
    path.write_text(json.dumps(c))
    return path


def run(a, cfg, out, ranks, threads):
    env = dict(os.environ, POCL_MAX_PTHREAD_COUNT=str(threads), **MPI_ENV)
    cmd = [a.tandem, "optimize", str(cfg), "--out", str(out), "--json"]
    if ranks > 1:
        cmd = [a.mpirun, "--oversubscribe", "-np", str(ranks), "-x", "POCL_MAX_PTHREAD_COUNT"] + cmd
    r = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)}: {r.stderr.strip()}")
    summary = json.loads(r.stdout)
    with open(out / "metrics.csv") as f:
        rows = list(csv.DictReader(f))
    summary["per_iteration"] = float(rows[-1]["seconds"]) / len(rows)
    summary["params"] = (out / "params.json").read_bytes()
    return summary


def larger_texture(tmp, width):
    """The globe's texture resampled (nearest) to width x width/2, as EXR."""
    import numpy as np
    import tandem
    image = np.asarray(tandem.read_image(str(SCENES / "textures" / "globe.png")))
    h, w = image.shape[:2]
    ys = (np.arange(width // 2) * h) // (width // 2)
    xs = (np.arange(width) * w) // width
    path = tmp / f"globe-{width}.exr"
    tandem.write_image(str(path), np.ascontiguousarray(image[ys][:, xs]))
    return path


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tandem", default=str(ROOT / "build" / "tandem"))
    ap.add_argument("--mpirun", default="mpirun")
    ap.add_argument("--iterations", type=int, default=24)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--threads", type=int, default=os.cpu_count())
    ap.add_argument("--textures", type=int, nargs="*", default=[128, 512, 1024])
    ap.add_argument("--gpu-view-ms", type=float, default=18.5)
    ap.add_argument("--pcie-gbs", type=float, default=25.0)
    ap.add_argument("--net-gbs", type=float, default=25.0)
    ap.add_argument("--latency-us", type=float, default=5.0)
    ap.add_argument("--out", type=pathlib.Path)
    a = ap.parse_args()
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="tandem-mpi-bench-"))
    lines = []

    def say(text=""):
        print(text, flush=True)
        lines.append(text)

    # 1. strong scaling: modes alternate within each round
    cfg = config(tmp, "globe", a.iterations)
    modes = [(1, a.threads), (1, 1), (a.threads, 1)]
    run(a, cfg, tmp / "warm", 1, a.threads)  # the kernel cache, outside the timings
    times = {m: [] for m in modes}
    params = {}
    for r in range(a.rounds):
        for ranks, threads in modes:
            s = run(a, cfg, tmp / f"scale-{ranks}-{threads}-{r}", ranks, threads)
            times[(ranks, threads)].append(s["per_iteration"])
            params.setdefault((ranks, threads), s["params"])
    same = len(set(params.values())) == 1
    med = {m: statistics.median(t) for m, t in times.items()}
    cpu = platform.processor() or platform.machine()
    say(f"Strong scaling: the globe job, {a.iterations} iterations of 8 views, median of "
        f"{a.rounds} alternating rounds; every mode ends on the same parameters: "
        f"{'yes' if same else 'NO'}")
    say()
    say("| ranks × PoCL threads | s / iteration | speed-up over 1 × 1 | rounds |")
    say("|---|---|---|---|")
    for ranks, threads in modes:
        say(f"| {ranks} × {threads} | {med[(ranks, threads)]:.4f} | "
            f"{med[(1, 1)] / med[(ranks, threads)]:.2f} | "
            f"{', '.join(f'{t:.4f}' for t in times[(ranks, threads)])} |")
    say()
    say(f"{a.threads} ranks × 1 thread over 1 rank × {a.threads} threads: "
        f"{med[(1, a.threads)] / med[(a.threads, 1)]:.3f} (above 1: the ranks are faster)")
    say()

    # 2. the exchanges at 2 ranks, per texture size
    say("The exchanges at 2 ranks (rank 0's, per iteration; median of the rounds):")
    say()
    say("| texture | parameters | bytes exchanged | exchange, ms | wait for the other rank, ms "
        "| iteration, ms | exchange ÷ iteration |")
    say("|---|---|---|---|---|---|---|")
    rate = None
    for width in a.textures:
        texture = None if width == 128 else larger_texture(tmp, width)
        c = config(tmp, f"tex{width}", max(4, a.iterations // 2), texture)
        found = []
        for r in range(a.rounds):
            s = run(a, c, tmp / f"ex-{width}-{r}", 2, 1)
            n = s["iterations"]
            found.append((s["exchange_seconds"] / n, s["exchange_wait_seconds"] / n,
                          s["exchange_bytes"] / n, s["per_iteration"]))
        ex, wait, nbytes, it = (statistics.median(f[i] for f in found) for i in range(4))
        rate = nbytes / ex if ex > 0 else None
        say(f"| {width} × {width // 2} | {3 * width * width // 2} | {nbytes / 1e6:.2f} MB | "
            f"{1e3 * ex:.2f} | {1e3 * wait:.2f} | {1e3 * it:.1f} | {ex / it:.3f} |")
    say()

    # 3. projection
    say(f"Projection (assumptions: one view's primal + adjoint {a.gpu_view_ms} ms on one GPU; "
        f"PCIe {a.pcie_gbs} GB/s each way; the host merge at {rate / 1e9:.2f} GB/s, measured "
        f"above at the largest texture; a ring all-reduce at {a.net_gbs} GB/s per link with "
        f"{a.latency_us} µs per step). Exchange ÷ iteration, for V views per iteration:")
    say()
    sizes = [256, 1024, 4096]
    ranks = [8, 16, 32, 64]
    say("| texture (RGB) | gradient bytes | " + " | ".join(f"{n} GPUs, V = {n}" for n in ranks)
        + " | " + " | ".join(f"{n} GPUs, V = {4 * n}" for n in ranks) + " |")
    say("|---|---|" + "---|" * (2 * len(ranks)))
    for size in sizes:
        b = 12.0 * 3 * size * size
        cells = []
        for per in (1, 4):
            for n in ranks:
                views = per * n
                render = math.ceil(views / n) * a.gpu_view_ms * 1e-3
                exchange = (2 * b / (a.pcie_gbs * 1e9) + b / rate +
                            2 * (n - 1) / n * b / (a.net_gbs * 1e9) +
                            2 * (n - 1) * a.latency_us * 1e-6)
                cells.append(f"{exchange / (render + exchange):.2f}")
        say(f"| {size}² | {b / 1e6:.1f} MB | " + " | ".join(cells) + " |")
    say()
    say(f"Measured on {cpu}, {os.cpu_count()} cores; `{' '.join(['python3', 'bench/mpi_bench.py'])}`")
    if a.out:
        a.out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
