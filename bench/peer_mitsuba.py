#!/usr/bin/env python3
"""Tandem against Mitsuba 3 on the same machine, side by side in one run (issue #10).

    bench/peer_mitsuba.py --install                # once: Mitsuba 3 into bench/.venv-mitsuba
    /usr/bin/python3 bench/peer_mitsuba.py [--json] [--csv FILE] [--plot FILE.png]

For each bundled scene (scenes/*.xml, converted by bench/peer_mitsuba_convert.py: box filter,
explicit GGX, float textures, resolved $defaults, absolute file paths; both renderers get the same
resolution, spp, max_depth and seeds 0, 1, ...), it prints:

1. Samples/s at --res^2 and --spp, both renderers on --threads threads: Tandem (`tandem render
   --json`), Mitsuba `llvm_ad_rgb` and `scalar_rgb`. The renders of each scene alternate, seed by
   seed, between Tandem and Mitsuba's llvm variant, so machine noise hits both alike; the rate is
   from the fastest of the seeds (other load only ever adds time). Compared times:
   - Tandem: `seconds`, the wall time of the render passes and the download of the image; also
     shown, `kernel_seconds`, the sum of the passes' OpenCL event times. Scene loading, BVH
     build and program build are outside both; one untimed 1-spp render per scene first fills
     PoCL's kernel cache, so no timed render compiles.
   - Mitsuba: the wall time of mi.render until dr.eval and dr.sync_thread return, after one
     untimed render of the same size and spp (it traces and compiles the kernels). It includes
     the tracing of the program that Dr.Jit repeats at every render (the compiled kernel comes
     from its cache); scene loading is outside it. `scalar_rgb`: --scalar-repeats renders after
     an untimed 1-spp one.
   - "cores busy": CPU time over wall time, Tandem's over its whole `tandem render` process,
     Mitsuba's over its timed renders. Below --threads, other work took the cores; the run also
     records the 1-minute load average before each scene.
2. Gradient-step time of the texture recovery in --config (scenes/cbox-wall-recover.json: the
   wall texture, its loss, spp + spp_grad, Adam and learning rate) at each --grad-sizes: Tandem's
   `tandem optimize` with plain PRB (`cv: none`; the time per iteration from metrics.csv's
   `seconds`, which leaves out set-up and the target render) against Mitsuba's `prb` integrator
   (`prbvolpath` for a scene with media, e.g. --config scenes/media-cube-recover.json)
   in a Python loop (mi.render with spp/spp_grad, the loss, dr.backward, Adam step, clamp to
   the parameter's range, params.update, evaluated and synchronised), both after --grad-warmup steps; the
   table shows the fastest of the --grad-iterations steps, and their mean.
3. The image difference in noise units, from the same renders as 1 (--seeds independent seeds
   per renderer): per channel, the relative difference of the image means and its z-score (the
   difference over its standard error, from the per-pixel sample variance over the seeds), the
   share of --tile^2 blocks whose own z passes 3 (0.27 % for pure noise) and the worst block.

Mitsuba is an optional benchmark dependency, never a build or test one. `--install` creates a
virtual environment (default bench/.venv-mitsuba, or --venv PATH) with the Python running this
script and pip-installs --mitsuba-spec and numpy into it; the Mitsuba side then runs in that
environment's Python (bench/peer_mitsuba_worker.py, JSON over a pipe), and this script needs only
the standard library (and matplotlib for --plot: on Debian 12, /usr/bin/python3 has it).

Mitsuba's llvm variants need libLLVM >= 16 (Dr.Jit aborts with LLVM 15, the version PoCL 3.1
links on Debian 12). On Debian 12 install `libllvm19` (`apt-get install libllvm19`, as root;
check with `apt-cache policy libllvm19`). The script finds the newest libLLVM >= 16 in the usual
library folders and points Dr.Jit at it through DRJIT_LIBLLVM_PATH, unless that is already set.
"""
import argparse
import csv
import glob
import json
import os
import platform
import re
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
from peer_mitsuba_convert import ConvertError, convert_file, parse_define  # noqa: E402
from peer_mitsuba_report import plot, tables, write_csv  # noqa: E402

BUNDLED = ["cbox", "cbox-wall", "three-spheres", "indirect-room", "env-probe", "gallery-lights",
           "media-cube", "media-plume"]
LLVM, SCALAR = "llvm_ad_rgb", "scalar_rgb"


def fail(what):
    sys.exit(f"peer_mitsuba: {what}")


# ---- the virtual environment and libLLVM ----

def venv_python(venv):
    return os.path.join(venv, "bin", "python")


def install(venv, spec):
    print(f"creating {venv} with {sys.executable}", file=sys.stderr)
    subprocess.run([sys.executable, "-m", "venv", venv], check=True)
    subprocess.run([venv_python(venv), "-m", "pip", "install", "--upgrade", spec, "numpy"],
                   check=True)


def find_libllvm():
    """(path, major) of the newest libLLVM >= 16 in the usual folders, or None."""
    found = []
    for folder in ["/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib64",
                   "/usr/lib", "/usr/local/lib"] + glob.glob("/usr/lib/llvm-*/lib"):
        for path in glob.glob(os.path.join(folder, "libLLVM*.so*")):
            m = re.search(r"libLLVM(?:-(\d+)[.\w]*\.so|\.so\.(\d+))", os.path.basename(path))
            if m and int(m.group(1) or m.group(2)) >= 16:
                found.append((int(m.group(1) or m.group(2)), path))
    return (max(found)[1], max(found)[0]) if found else None


def worker_env(variant):
    env = dict(os.environ)
    if variant.startswith("llvm") and "DRJIT_LIBLLVM_PATH" not in env:
        llvm = find_libllvm()
        if llvm is None:
            fail("Mitsuba's llvm_ad_rgb needs libLLVM >= 16 and none was found (Dr.Jit aborts "
                 "with LLVM 15). On Debian 12: apt-get install libllvm19 (as root); elsewhere "
                 "set DRJIT_LIBLLVM_PATH to a libLLVM.so of version 16 or newer")
        env["DRJIT_LIBLLVM_PATH"] = llvm[0]
    return env


def tandem_env(threads):
    env = dict(os.environ)
    env["POCL_MAX_PTHREAD_COUNT"] = str(threads)  # PoCL 3's pthread device (Debian 12)
    env["POCL_CPU_MAX_CU_NUM"] = str(threads)  # the same in later PoCL's cpu device
    return env


class Mitsuba:
    """bench/peer_mitsuba_worker.py in the virtual environment, one JSON line each way."""

    def __init__(self, venv, threads, variant, python=None):
        if python is None:
            python = venv_python(venv)
            if not os.path.exists(python):
                fail(f"no virtual environment at {venv}: run `bench/peer_mitsuba.py --install` "
                     "first (or give --venv PATH, or --python)")
        self.proc = subprocess.Popen([python, os.path.join(HERE, "peer_mitsuba_worker.py"),
                                      str(threads)], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, text=True, env=worker_env(variant))

    def __call__(self, cmd, **req):
        self.proc.stdin.write(json.dumps(dict(req, cmd=cmd)) + "\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            fail(f"the Mitsuba worker ended during '{cmd}' (its messages are above)")
        answer = json.loads(line)
        if "error" in answer:
            fail(f"Mitsuba, {cmd} {req.get('xml', '')}: {answer['error']}")
        return answer["ok"]

    def close(self):
        self.proc.stdin.write(json.dumps({"cmd": "quit"}) + "\n")
        self.proc.stdin.close()
        self.proc.wait()


# ---- Tandem ----

def tandem_render(args, scene, spp, seed, out):
    cmd = [args.tandem, "render", scene, "--spp", str(spp), "--seed", str(seed), "--out", out,
           "--json"] + [f"-D{n}={v}" for n, v in args.defines_all]
    if args.device:
        cmd += ["--device", args.device]
    t0, c0 = time.perf_counter(), children_cpu_seconds()
    r = subprocess.run(cmd, capture_output=True, text=True, env=tandem_env(args.threads))
    if r.returncode:
        fail(f"{' '.join(cmd)} failed:\n{r.stderr}")
    return dict(json.loads(r.stdout), process_seconds=time.perf_counter() - t0,
                process_cpu_seconds=children_cpu_seconds() - c0)


def children_cpu_seconds():
    t = os.times()
    return t.children_user + t.children_system


def tandem_optimize(args, config, size, tmp):
    """Seconds per iteration of `tandem optimize` (plain PRB) of `config` at size^2."""
    c = json.load(open(config))
    folder = os.path.dirname(os.path.abspath(config))
    c["scene"] = os.path.join(folder, c["scene"])
    c["target"]["scene"] = os.path.join(folder, c["target"]["scene"])
    for part in (c, c["target"]):
        part["defines"] = dict(part.get("defines", {}), res=size)
    total = args.grad_warmup + args.grad_iterations
    c.update(cv="none", iterations=total, checkpoint_every=total, image_error_spp=1)
    path = os.path.join(tmp, f"optimize-{size}.json")
    json.dump(c, open(path, "w"))
    out = os.path.join(tmp, f"optimize-{size}")
    cmd = [args.tandem, "optimize", path, "--out", out] + (
        ["--device", args.device] if args.device else [])
    t0, c0 = time.perf_counter(), children_cpu_seconds()
    r = subprocess.run(cmd, capture_output=True, text=True, env=tandem_env(args.threads))
    if r.returncode:
        fail(f"{' '.join(cmd)} failed:\n{r.stderr}")
    cores = (children_cpu_seconds() - c0) / (time.perf_counter() - t0)  # the whole process
    rows = list(csv.DictReader(open(os.path.join(out, "metrics.csv"))))
    cumulative = [float(row["seconds"]) for row in rows]
    steps = [b - a for a, b in zip([0.0] + cumulative, cumulative)]
    timed = steps[args.grad_warmup:]
    return {"first_seconds": steps[0], "seconds": steps, "cores": cores,
            "mean_seconds": sum(timed) / len(timed),
            "median_seconds": sorted(timed)[len(timed) // 2],
            "losses": [float(row["loss"]) for row in rows]}


# ---- the three measurements ----

def convert(args, scene, tmp, integrator="path", defines=()):
    try:
        text = convert_file(scene, list(args.defines_all) + list(defines), integrator)
    except ConvertError as e:
        fail(str(e))
    path = os.path.join(tmp, os.path.basename(scene)[:-4] + f"-{integrator}-mitsuba.xml")
    open(path, "w").write(text)
    return path


def measure_scene(args, mitsuba, name, tmp):
    scene = os.path.join(ROOT, "scenes", name + ".xml")
    xml = convert(args, scene, tmp)
    def say(what):
        if not args.quiet:
            print(f"[{name}] {what}", file=sys.stderr)

    load_before = loadavg()
    say(f"Tandem warm-up, Mitsuba {args.variant} load and first render")
    tandem_render(args, scene, 1, 0xFFFFFF, os.path.join(tmp, "warm.exr"))
    first = mitsuba("load", variant=args.variant, xml=xml, spp=args.spp)
    tandem, llvm, images = [], [], []
    for seed in range(args.seeds):
        say(f"seed {seed + 1}/{args.seeds}: Tandem, Mitsuba {args.variant}")
        images.append(os.path.join(tmp, f"{name}-{seed}.exr"))
        tandem.append(tandem_render(args, scene, args.spp, seed, images[-1]))
        llvm.append(mitsuba("render", variant=args.variant, xml=xml, spp=args.spp, seed=seed,
                            keep=True))
    width, height = tandem[0]["width"], tandem[0]["height"]
    if (first["width"], first["height"]) != (width, height):
        fail(f"{name}: Tandem renders {width}x{height}, Mitsuba {first['width']}x"
             f"{first['height']}")
    samples = width * height * args.spp
    row = {"scene": name, "width": width, "height": height, "spp": args.spp,
           "loadavg_before": load_before,
           "tandem_seconds": [t["seconds"] for t in tandem],
           "tandem_kernel_seconds": [t["kernel_seconds"] for t in tandem],
           "llvm_seconds": [m["seconds"] for m in llvm],
           # cores busy: CPU time over wall time; Tandem's over its whole process (start-up,
           # scene loading and image output included), Mitsuba's over the timed renders
           "tandem_cores": sum(t["process_cpu_seconds"] for t in tandem) / sum(
               t["process_seconds"] for t in tandem),
           "llvm_cores": sum(m["cpu_seconds"] for m in llvm) / sum(m["seconds"] for m in llvm),
           "llvm_first_render_seconds": first["first_render_seconds"]}
    row["tandem_msps"] = samples / min(row["tandem_seconds"]) / 1e6
    row["tandem_kernel_msps"] = samples / min(row["tandem_kernel_seconds"]) / 1e6
    row["llvm_msps"] = samples / min(row["llvm_seconds"]) / 1e6
    if args.scalar_repeats:
        say(f"Mitsuba {SCALAR}: {args.scalar_repeats} render(s)")
        mitsuba("load", variant=SCALAR, xml=xml, spp=1)
        scalar = [mitsuba("render", variant=SCALAR, xml=xml, spp=args.spp, seed=seed)
                  for seed in range(args.scalar_repeats)]
        row["scalar_seconds"] = [m["seconds"] for m in scalar]
        row["scalar_cores"] = sum(m["cpu_seconds"] for m in scalar) / sum(row["scalar_seconds"])
        row["scalar_msps"] = samples / min(row["scalar_seconds"]) / 1e6
    say("image difference")
    mean = os.path.join(tmp, f"{name}-mitsuba-mean.exr") if args.keep else None
    row["image"] = mitsuba("compare", xml=xml, tandem=images, tile=args.tile, save=mean)
    return row


def measure_grad(args, mitsuba, tmp):
    c = json.load(open(args.config))
    if len(c["params"]) != 1:
        fail(f"{args.config}: the gradient benchmark takes exactly one parameter")
    (param, p), = c["params"].items()
    if not isinstance(p.get("init", 0.5), (int, float)):
        fail(f"{args.config}: params.{param}.init must be a number for the Mitsuba side")
    if c.get("loss", "l2") not in ("l1", "l2") or c.get("optimizer", "adam") != "adam":
        fail(f"{args.config}: the Mitsuba side mirrors loss l1 or l2 with Adam only")
    if "scene" not in c["target"]:
        fail(f"{args.config}: the Mitsuba side needs a target scene, not an image")
    folder = os.path.dirname(os.path.abspath(args.config))
    # the parameter's range, which both sides clamp to after each step
    listed = subprocess.run([args.tandem, "params", os.path.join(folder, c["scene"]), "--json"],
                            capture_output=True, text=True, check=True).stdout
    entry = next(e for e in json.loads(listed) if e["name"] == param)
    lower, upper = float(entry["lower"]), float(entry["upper"])  # "inf" parses
    rows = []
    for size in args.grad_sizes:
        if not args.quiet:
            print(f"[gradient] {size}x{size}: Tandem, Mitsuba prb", file=sys.stderr)
        defines = [(k, str(v)) for k, v in c.get("defines", {}).items()] + [("res", str(size))]
        tdefines = [(k, str(v)) for k, v in c["target"].get("defines", {}).items()] + [
            ("res", str(size))]
        xml = convert(args, os.path.join(folder, c["scene"]), tmp, "prb", defines)
        target_xml = convert(args, os.path.join(folder, c["target"]["scene"]), tmp, "path",
                             tdefines)
        load_before = loadavg()
        tandem = tandem_optimize(args, args.config, size, tmp)
        mi = mitsuba("grad", variant=args.variant, xml=xml, target_xml=target_xml, param=param,
                     lower=lower, upper=upper, lr=p["lr"], init=p.get("init", 0.5), loss=c.get("loss", "l2"),
                     beta1=c.get("beta1", 0.9), beta2=c.get("beta2", 0.999),
                     epsilon=c.get("epsilon", 1e-8), spp=c.get("spp", 4),
                     spp_grad=c.get("spp_grad", c.get("spp", 4)),
                     target_spp=c["target"].get("spp", 256), target_seed=0x7A4DE4,
                     warmup=args.grad_warmup, iterations=args.grad_iterations)
        rows.append({"size": size, "loadavg_before": load_before, "param": param,
                     "mitsuba_param": mi.pop("key"),
                     "spp": c.get("spp", 4), "spp_grad": c.get("spp_grad", c.get("spp", 4)),
                     "loss": c.get("loss", "l2"), "tandem": tandem, "mitsuba": mi})
    return rows


# ---- the run ----

def loadavg():
    """The machine's 1-minute load average: other work competing for the cores."""
    return float(open("/proc/loadavg").read().split()[0])


def machine():
    cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo")
                if line.startswith("model name")), platform.processor())
    release = dict(re.findall(r'^(\w+)="?([^"\n]*)"?', open("/etc/os-release").read(), re.M))
    head = subprocess.run(["git", "-C", ROOT, "describe", "--always", "--dirty"],
                          capture_output=True, text=True).stdout.strip()
    return {"cpu": cpu, "logical_cpus": os.cpu_count(), "os": release.get("PRETTY_NAME", ""),
            "tandem_commit": head}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 epilog="\n\n".join(__doc__.split("\n\n")[1:]),
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--install", action="store_true",
                    help="create the virtual environment and install Mitsuba into it, then exit")
    ap.add_argument("--venv", default=os.path.join(HERE, ".venv-mitsuba"),
                    help="the virtual environment (default: %(default)s)")
    ap.add_argument("--mitsuba-spec", default="mitsuba==3.9.1",
                    help="what --install asks pip for (default: %(default)s, the tested version)")
    ap.add_argument("--python",
                    help="a Python that imports mitsuba, used instead of --venv (e.g. on a GPU "
                         "machine with the wheels installed by hand)")
    ap.add_argument("--variant", default=LLVM, choices=[LLVM, "cuda_ad_rgb"],
                    help="Mitsuba's variant for the renders and the gradient steps: "
                         "cuda_ad_rgb on an NVIDIA GPU, against Tandem on --device (the "
                         "'llvm' fields of the JSON hold it; default: %(default)s)")
    ap.add_argument("--tandem", default=os.path.join(ROOT, "build", "tandem"),
                    help="the tandem binary (default: %(default)s)")
    ap.add_argument("--device", help="Tandem's OpenCL device (index or name substring)")
    ap.add_argument("--scenes", default=",".join(BUNDLED),
                    help="bundled scenes, comma-separated (default: all)")
    ap.add_argument("-D", dest="defines", action="append", type=parse_define, default=[],
                    metavar="NAME=VALUE", help="override a scene <default> in both renderers")
    ap.add_argument("--res", type=int, default=256, help="square resolution (default: 256)")
    ap.add_argument("--spp", type=int, default=64, help="samples per pixel (default: 64)")
    ap.add_argument("--seeds", type=int, default=4,
                    help="timed renders per scene and renderer, with seeds 0, 1, ...; also the "
                         "independent images of the difference (default: 4, at least 2)")
    ap.add_argument("--scalar-repeats", type=int, default=1,
                    help="timed Mitsuba scalar_rgb renders per scene; 0 skips it (default: 1)")
    ap.add_argument("--threads", type=int, default=2, help="threads of each (default: 2)")
    ap.add_argument("--tile", type=int, default=16, help="block side of the tile z (default: 16)")
    ap.add_argument("--config", default=os.path.join(ROOT, "scenes", "cbox-wall-recover.json"),
                    help="the optimization of the gradient benchmark (default: %(default)s)")
    ap.add_argument("--grad-sizes", default="128,256",
                    help="square resolutions of the gradient steps (default: %(default)s)")
    ap.add_argument("--grad-warmup", type=int, default=3, help="untimed steps (default: 3)")
    ap.add_argument("--grad-iterations", type=int, default=10, help="timed steps (default: 10)")
    ap.add_argument("--skip-render", action="store_true", help="no samples/s or images")
    ap.add_argument("--skip-grad", action="store_true", help="no gradient steps")
    ap.add_argument("--json", action="store_true", help="print JSON instead of the tables")
    ap.add_argument("--csv", help="also write the headline numbers to this CSV file")
    ap.add_argument("--plot", help="also plot samples/s and step times to this PNG (matplotlib)")
    ap.add_argument("--from-json", metavar="FILE",
                    help="measure nothing: print the tables (and --csv, --plot) of a saved --json")
    ap.add_argument("--keep", help="keep the converted scenes, Tandem's renders and Mitsuba's mean "
                                   "image per scene in this folder")
    ap.add_argument("--quiet", action="store_true", help="no progress on stderr")
    args = ap.parse_args()

    if args.install:
        install(args.venv, args.mitsuba_spec)
        llvm = find_libllvm()
        print(f"installed into {args.venv}; libLLVM >= 16: "
              f"{llvm[0] if llvm else 'NOT FOUND (apt-get install libllvm19)'}")
        return
    if args.from_json:
        report(args, json.load(open(args.from_json)))
        return
    if args.seeds < 2:
        fail("--seeds must be at least 2 (the image difference needs a sample variance)")
    if not os.access(args.tandem, os.X_OK):
        fail(f"no tandem binary at {args.tandem}: build it, or give --tandem")
    args.grad_sizes = [int(s) for s in args.grad_sizes.split(",") if s]
    args.defines_all = list(args.defines) + [("res", str(args.res)), ("spp", str(args.spp))]
    scenes = [s for s in args.scenes.split(",") if s]
    for s in scenes:
        if not os.path.exists(os.path.join(ROOT, "scenes", s + ".xml")):
            fail(f"no scene scenes/{s}.xml")

    tmp_holder = None if args.keep else tempfile.TemporaryDirectory(prefix="peer-mitsuba-")
    tmp = args.keep or tmp_holder.name
    os.makedirs(tmp, exist_ok=True)
    mitsuba = Mitsuba(args.venv, args.threads, args.variant, args.python)
    try:
        result = {"machine": machine(), "mitsuba": mitsuba("hello"), "variant": args.variant,
                  "threads": args.threads,
                  "res": args.res, "spp": args.spp, "seeds": args.seeds, "tile": args.tile,
                  "grad_warmup": args.grad_warmup, "grad_iterations": args.grad_iterations,
                  "command": " ".join([os.path.relpath(sys.argv[0], ROOT)] + sys.argv[1:]),
                  # Tandem's overrides (TANDEM_WAVEFRONT and the like) and PoCL's (its work-group
                  # method, which Tandem otherwise chooses), which change what it runs
                  "tandem_environment": {k: v for k, v in sorted(os.environ.items())
                                         if k.startswith("TANDEM_") or k.startswith("POCL_")},
                  "render": [], "grad": []}
        if not args.skip_render:
            result["render"] = [measure_scene(args, mitsuba, s, tmp) for s in scenes]
        if not args.skip_grad:
            result["grad"] = measure_grad(args, mitsuba, tmp)
        result["loadavg_after"] = loadavg()
    finally:
        mitsuba.close()
    report(args, result)


def report(args, result):
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(tables(result), end="")
    if args.csv:
        write_csv(result, args.csv)
    if args.plot:
        plot(result, args.plot)


if __name__ == "__main__":
    main()
