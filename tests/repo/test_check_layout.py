#!/usr/bin/env python3
"""check_layout.py's ban on built-in math in kernels catches every function it names: each one,
planted alone in a kernel file of a small temporary tree, makes the check fail naming it, while
the correctly rounded built-ins, the project's own functions and mentions in comments pass. The
same way: a getenv below the entry points, a kernel that no product code launches (a test probe
left in kernels/) and a README over 200 lines are reported, and their allowed forms are not.

    python3 tests/repo/test_check_layout.py

The list below is written out from the OpenCL C 1.2 specification (sections 6.12.2-6.12.5 and
table 7.1), independently of the check's regular expression. Standard library only.
"""
import contextlib
import io
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import check_layout  # noqa: E402

# Each implementation rounds these its own way (several ulp, implementation-defined, or computed
# with contractions the compiler chooses).
BANNED = """
    sin cos tan asin acos atan atan2 sinh cosh tanh asinh acosh atanh sinpi cospi tanpi asinpi
    acospi atanpi atan2pi sincos exp exp2 exp10 expm1 log log2 log10 log1p pow powr pown rootn
    cbrt rsqrt hypot erf erfc tgamma lgamma lgamma_r
    native_cos native_divide native_exp native_exp2 native_exp10 native_log native_log2
    native_log10 native_powr native_recip native_rsqrt native_sin native_sqrt native_tan
    half_cos half_divide half_exp half_exp2 half_exp10 half_log half_log2 half_log10 half_powr
    half_recip half_rsqrt half_sin half_sqrt half_tan
    mad dot cross length distance normalize fast_length fast_distance fast_normalize
    mix smoothstep degrees radians
""".split()
# Correctly rounded (or exact), and names that only contain a banned one.
ALLOWED = """
    sqrt fma fabs floor ceil round trunc rint fmin fmax fmod clamp sign step copysign
    det_sin det_atan2 half_vector path_length bsdf_mad normalized
""".split()


def check(tree, rel, text):
    """Runs check_layout on `tree` with `text` written to `rel`; returns (exit code, output)."""
    path = os.path.join(tree, rel)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        f.write(text)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = check_layout.main(tree)
    os.remove(path)
    return code, out.getvalue()


def check_product_rules(tree):
    """The entry-point, probe and README rules: each violation reported, each allowed form not."""
    failures = []
    getenv = 'const char* v = std::getenv("TANDEM_X");\n'
    for rel in ("core/render/features.cpp", "runtime/device.cpp", "core/inverse/x.h",
                "cli/main.cpp", "python/src/module.cpp"):
        code, out = check(tree, rel, getenv)
        if code != 1 or f"{rel}:1: reads the environment" not in out:
            failures.append(f"getenv in {rel}: exit {code}, output {out.strip()!r}")
    for rel in ("runtime/tuning.cpp", "tests/core/x.cpp", "fuzz/x.cpp", "core/render/x.cpp"):
        text = getenv if rel != "core/render/x.cpp" else "// std::getenv(\"X\") is not read here\n"
        code, out = check(tree, rel, text)
        if code != 0:
            failures.append(f"{rel} is reported: {out.strip()!r}")
    probe = "__kernel void layout_probe(__global uint* out) {}\n"
    code, out = check(tree, "kernels/layout.cl", probe)
    if code != 1 or "kernel layout_probe is launched by no product code" not in out:
        failures.append(f"a probe kernel in kernels/: exit {code}, output {out.strip()!r}")
    with open(os.path.join(tree, "core", "launcher.cpp"), "w") as f:
        f.write('auto& k = scene.kernel("render.cl", "render_pass");\n')
    code, out = check(tree, "kernels/render.cl", "__kernel void render_pass(uint n) {}\n")
    os.remove(os.path.join(tree, "core", "launcher.cpp"))
    if code != 0:
        failures.append(f"a launched kernel is reported: {out.strip()!r}")
    for lines, want in ((200, 0), (201, 1)):
        code, out = check(tree, "README.md", "line\n" * lines)
        if code != want:
            failures.append(f"a README of {lines} lines: exit {code}, output {out.strip()!r}")
    return failures


def main():
    failures = []
    with tempfile.TemporaryDirectory() as tree:
        os.makedirs(os.path.join(tree, "kernels", "shared"))
        code, out = check(tree, "kernels/empty.cl", "// nothing\n")
        if code != 0:
            failures.append(f"an empty kernel file fails: {out}")
        for name in BANNED:
            for rel in ("kernels/probe.cl", "kernels/path/probe.h", "kernels/shared/probe.h"):
                text = f"// calls {name}\nfloat f(float x) {{\n    return {name} (x, x);\n}}\n"
                code, out = check(tree, rel, text)
                if code != 1 or f"{rel}:3: calls the built-in {name}()" not in out:
                    failures.append(f"{name} in {rel}: exit {code}, output {out.strip()!r}")
        for name in ALLOWED:
            text = f"float f(float x) {{\n    return {name}(x) + s.length(x); // dot(x, x)\n}}\n"
            code, out = check(tree, "kernels/probe.cl", text)
            if code != 0:
                failures.append(f"{name} is reported: {out.strip()!r}")
        # det_math.h itself may call the built-ins (its DET_MATH=0 mode), and host code is free
        code, out = check(tree, check_layout.DET_MATH, "float f(float x) { return sin(x); }\n")
        if code != 0:
            failures.append(f"det_math.h is reported: {out.strip()!r}")
        code, out = check(tree, "core/render/x.cpp", "float f(float x) { return std::sin(x); }\n")
        if code != 0:
            failures.append(f"host code is reported: {out.strip()!r}")
        failures += check_product_rules(tree)
    for f in failures:
        print("FAIL: " + f)
    print(f"{len(BANNED)} banned built-ins planted in 3 kernel folders, {len(ALLOWED)} allowed names")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
