#!/usr/bin/env python3
"""Which kernel forms PoCL's work-group vectoriser turns into SIMD across work items.

    scripts/vectorize_probe.py [--items N] [--kernels K,...] [--cl FILE]

Builds scripts/vectorize_probe.cl (or FILE) on the first CPU OpenCL device with the options Tandem
uses, runs each kernel over N work items (default 2^22; best of 4 runs, event time) and prints,
per kernel, the loop vectoriser's verdict on the work-item loop (POCL_VECTORIZER_REMARKS=1:
"vectorized loop (vectorization width: W ...)" or why not) and millions of work items per second.
Soa_sincos and soa_sincos_switch must give the same bits; the script checks it. A research tool for
issue #10 (a wavefront whose stages PoCL vectorises); needs pyopencl from PyPI (pip install
pyopencl numpy), not a build or test dependency. What it showed: docs/wavefront.md.
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def run_one(cl_file, kernel, items, cache, no_slp):
    """Runs one kernel in a child process (PoCL prints the remarks on its stderr)."""
    code = r'''
import hashlib, os, sys, numpy as np, pyopencl as cl
src, kernel, n = open(sys.argv[1]).read(), sys.argv[2], int(sys.argv[3])
dev = [d for p in cl.get_platforms() for d in p.get_devices() if d.type & cl.device_type.CPU][0]
ctx = cl.Context([dev])
q = cl.CommandQueue(ctx, properties=cl.command_queue_properties.PROFILING_ENABLE)
if os.environ.get("PROBE_NO_SLP") == "1":  # as runtime/pocl_llvm.h does, in PoCL's libLLVM
    import ctypes
    llvm = [l.split()[-1] for l in open("/proc/self/maps") if "/libLLVM" in l][0]
    argv = (ctypes.c_char_p * 2)(b"probe", b"-slp-threshold=1000000")
    ctypes.CDLL(llvm).LLVMParseCommandLineOptions(2, argv, b"")
prg = cl.Program(ctx, src).build(options=["-cl-std=CL1.2", "-cl-fp32-correctly-rounded-divide-sqrt",
                                          "-I", sys.argv[4]])
a = (np.random.default_rng(1).normal(size=n) * 3).astype(np.float32)
mf = cl.mem_flags
bin_ = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=a)
o0 = cl.Buffer(ctx, mf.WRITE_ONLY, 16 * n)
o1 = cl.Buffer(ctx, mf.WRITE_ONLY, 4 * n)
k = getattr(prg, kernel)
best = 1e9
for r in range(4):
    e = k(q, (n,), (64,), bin_, o0, o1, np.uint32(r))
    e.wait()
    best = min(best, (e.profile.end - e.profile.start) * 1e-9)
x = np.empty(4 * n, np.uint32)
y = np.empty(n, np.uint32)
cl.enqueue_copy(q, x, o0)
cl.enqueue_copy(q, y, o1)
print("RESULT %.6f %s" % (n / best * 1e-6, hashlib.sha1(x[:n].tobytes() + y.tobytes()).hexdigest()))
'''
    env = dict(os.environ, POCL_VECTORIZER_REMARKS="1", POCL_CACHE_DIR=cache,
               PROBE_NO_SLP="1" if no_slp else "0")
    p = subprocess.run([sys.executable, "-c", code, cl_file, kernel, str(items),
                        os.path.join(ROOT, "kernels")], capture_output=True, text=True, env=env)
    if p.returncode != 0:
        sys.exit("vectorize_probe: %s failed: %s" % (kernel, (p.stderr or p.stdout).strip()[-400:]))
    m = re.search(r"RESULT (\S+) (\S+)", p.stdout)
    remarks = re.findall(r"(vectorized loop \([^)]*\)|loop not vectorized: [^<\n]*)",
                         p.stderr + p.stdout)
    verdict = sorted(set(r for r in remarks if "loop not vectorized" in r or "vectorized loop" in r))
    return float(m.group(1)), m.group(2), verdict


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--items", type=int, default=1 << 22)
    ap.add_argument("--no-slp", action="store_true",
                    help="turn LLVM's SLP vectoriser off in PoCL first (runtime/pocl_llvm.h)")
    ap.add_argument("--cl", default=os.path.join(HERE, "vectorize_probe.cl"))
    ap.add_argument("--kernels", default="soa_arithmetic,aos_arithmetic,soa_rng,soa_sincos,"
                                         "soa_sincos_switch")
    a = ap.parse_args()
    try:
        import pyopencl  # noqa: F401
    except ImportError:
        sys.exit("vectorize_probe: needs pyopencl and numpy (pip install pyopencl numpy)")
    outputs = {}
    print("| kernel | M items/s | the work-item loop |")
    print("|---|---|---|")
    with tempfile.TemporaryDirectory() as cache:
        for k in a.kernels.split(","):
            rate, digest, verdict = run_one(a.cl, k, a.items, cache, a.no_slp)
            outputs[k] = digest
            print("| %s | %.1f | %s |" % (k, rate, "; ".join(verdict) or "no remark"))
    if "soa_sincos" in outputs and "soa_sincos_switch" in outputs:
        same = outputs["soa_sincos"] == outputs["soa_sincos_switch"]
        print("\nsoa_sincos and soa_sincos_switch give the same bits: %s" % ("yes" if same else "NO"))
        if not same:
            sys.exit(1)


if __name__ == "__main__":
    main()
