#!/usr/bin/env python3
"""Checks the repository's shape: no include runs from a lower layer to a higher one, no source
file outside tests/ is over 500 lines, nothing refers to files outside the repository, every
repository path a file cites (core/..., kernels/..., tests/... with an extension) exists, the
README stays a user's page (at most 200 lines; the reference is in docs/), the environment is read
in one place (ENV_READERS: runtime/tuning.cpp makes the Tuning the entry points pass down), and the product's kernels hold no test probe (every kernel in kernels/ is launched by
name from the product's host code: core/, runtime/, cli/ or python/src/; probes live in
tests/kernels/probes).

    python3 tests/repo/check_layout.py REPO_ROOT

Layers, lowest first; a file may include its own layer and those below it:
    kernels/shared < runtime < core/io < core/scene < core/bvh < core/render < core/inverse
    < bench < cli (the executable), python (the module; beside cli, above core), fuzz (the
    libFuzzer harnesses; beside cli)
Kernel sources (kernels/*.cl, kernels/path/*.h) include only kernels/, and call no built-in that
OpenCL lets each implementation round its own way (sin, cos, acos, atan2, exp, pow, rsqrt,
native_*, half_*, mad, dot, length, normalize, ...: BUILTIN_MATH below): kernels use
kernels/shared/det_math.h and the correctly rounded operations, which give the same bits
everywhere. Exits 1 listing every violation. tests/repo/test_check_layout.py plants each banned
call in a copy of a tree and checks that it is reported.
"""
import os
import re
import sys

LAYERS = ["kernels", "runtime", "core/io", "core/scene", "core/bvh", "core/render", "core/inverse",
          "bench", "cli", "python", "fuzz"]
MAX_LINES = 500
SOURCE_EXT = (".cpp", ".h", ".cl", ".py", ".cmake", ".sh")
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')
# OpenCL C 1.2 built-ins whose float results each implementation may round its own way: the
# transcendentals and rsqrt (section 7.4, table 7.1 allows them several ulp); the native_ and
# half_ forms (implementation-defined accuracy); mad ("any value allowed" for a * b + c); and the
# geometric and common functions the specification lets be computed with contractions (mad or
# fma: section 6.12.5 for dot, cross, length, distance, normalize and their fast_ forms, 6.12.4
# for mix, smoothstep, degrees and radians). The exactly rounded ones stay allowed: fabs, floor,
# ceil, round, trunc, rint, fmin, fmax, fmod, fma, clamp, sign, step, and sqrt and / with
# -cl-fp32-correctly-rounded-divide-sqrt.
BUILTIN_MATH = re.compile(
    r"(?<![\w.])(native_\w+|half_(?:cos|divide|exp|exp2|exp10|log|log2|log10|powr|recip|rsqrt|"
    r"sin|sqrt|tan)|(?:fast_)?(?:length|distance|normalize)|"
    r"(?:a?(?:sin|cos|tan)h?|atan2)(?:pi)?|sincos|exp|exp2|exp10|expm1|log|log2|log10|log1p|"
    r"pow|powr|pown|rootn|cbrt|rsqrt|hypot|erf|erfc|tgamma|lgamma|lgamma_r|"
    r"mad|dot|cross|mix|smoothstep|degrees|radians)\s*\(")
DET_MATH = "kernels/shared/det_math.h"
README_MAX_LINES = 200
# The files that may read the environment: runtime/tuning.cpp, which turns it into the one Tuning
# (tuning_from_environment, called by the entry points), and the harnesses of the tests and the
# fuzzers (their own switches).
ENV_READERS = ("runtime/tuning.cpp", "tests/", "fuzz/")
GETENV = re.compile(r"(?<![\w.])(?:std::)?(?:secure_)?getenv\s*\(")
KERNEL = re.compile(r"^\s*__kernel\s+void\s+(\w+)\s*\(", re.M)
PRODUCT_HOST = ("core/", "runtime/", "cli/", "python/src/")
OUTSIDE = re.compile(r"\.\./shared|papers/0\d\d|METHOD\.md|DESIGN\.md|RESTIR\.md|CONVENTIONS\.md")
CITED = re.compile(r"(?<![\w/.$])((?:core|kernels|runtime|tests|bench|cli|scripts|docs|scenes|cmake)/"
                   r"[A-Za-z0-9_./-]*[A-Za-z0-9_]\.(?:h|cpp|cl|py|md|sh|json|xml|cmake))\b")
# Files whose cited paths are not the repository's: synthetic trees of a test.
CITES_EXEMPT = {"tests/runtime/test_program.cpp", "tests/repo/test_check_layout.py"}


def layer_of(path):
    """Index in LAYERS of a repository-relative path or include target; None if unlayered."""
    if path.startswith("shared/"):  # kernels/shared, included as "shared/..."
        return 0
    best = None
    for i, prefix in enumerate(LAYERS):
        if path == prefix or path.startswith(prefix + "/"):
            best = i
    return best


def main(root):
    problems = []
    kernels = {}        # kernel name -> the kernels/ file that defines it
    host_strings = set()  # string literals of the product's host code
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = [d for d in dirnames if not d.startswith(".") and d not in ("build",)]
        for name in filenames:
            full = os.path.join(dirpath, name)
            rel = os.path.relpath(full, root).replace(os.sep, "/")
            if rel.startswith("build") or not (name.endswith(SOURCE_EXT) or name.endswith(".md")):
                continue
            with open(full, encoding="utf-8", errors="replace") as f:
                lines = f.readlines()
            text = "".join(lines)
            if rel != "tests/repo/check_layout.py" and OUTSIDE.search(text):
                problems.append(f"{rel}: refers to a file outside the repository "
                                f"({OUTSIDE.search(text).group(0)})")
            if rel not in CITES_EXEMPT:
                base = os.path.dirname(full)
                for number, line in enumerate(lines, 1):
                    for m in CITED.finditer(line):
                        cited = m.group(1)
                        if not any(os.path.exists(os.path.join(d, cited))
                                   for d in (root, base, os.path.join(root, "kernels"))):
                            problems.append(f"{rel}:{number}: cites {cited}, which does not exist")
            if rel == "README.md" and len(lines) > README_MAX_LINES:
                problems.append(f"README.md: {len(lines)} lines (more than {README_MAX_LINES}: "
                                f"reference material goes in docs/)")
            if not name.endswith(SOURCE_EXT):
                continue
            if name.endswith((".cpp", ".h")) and not rel.startswith(ENV_READERS):
                for number, line in enumerate(lines, 1):
                    if GETENV.search(line.split("//")[0]):
                        problems.append(f"{rel}:{number}: reads the environment, which only "
                                        f"runtime/tuning.cpp does (the entry points pass its "
                                        f"Tuning down)")
            if rel.startswith("kernels/") and name.endswith(".cl"):
                for m in KERNEL.finditer(text):
                    kernels[m.group(1)] = rel
            if rel.startswith(PRODUCT_HOST) and name.endswith((".cpp", ".h")):
                host_strings.update(re.findall(r'"(\w+)"', text))
            if not rel.startswith("tests/") and len(lines) > MAX_LINES:
                problems.append(f"{rel}: {len(lines)} lines (more than {MAX_LINES})")
            own = layer_of(rel)
            if own == 0 and rel != DET_MATH and name.endswith((".h", ".cl")):
                for number, line in enumerate(lines, 1):
                    code = line.split("//")[0]
                    m = BUILTIN_MATH.search(code)
                    if m:
                        problems.append(f"{rel}:{number}: calls the built-in {m.group(1)}(), "
                                        f"which each OpenCL implementation rounds its own way; "
                                        f"use {DET_MATH} or +, -, *, fma, / and sqrt")
            if own is None or not name.endswith((".cpp", ".h", ".cl")):
                continue
            for number, line in enumerate(lines, 1):
                m = INCLUDE.match(line)
                if not m:
                    continue
                target = m.group(1)
                if own == 0:  # kernel code includes kernel code only, by relative path
                    if layer_of(target) not in (None, 0) and not target.startswith("shared/"):
                        problems.append(f"{rel}:{number}: kernel code includes {target}")
                    continue
                theirs = layer_of(target)
                if theirs is not None and theirs > own:
                    problems.append(f"{rel}:{number}: includes {target}, a higher layer "
                                    f"({LAYERS[theirs]} above {LAYERS[own]})")
    for kernel, rel in sorted(kernels.items()):
        if kernel not in host_strings:
            problems.append(f"{rel}: kernel {kernel} is launched by no product code "
                            f"({', '.join(PRODUCT_HOST)}): a test probe or a benchmark's kernel "
                            f"belongs with its tests or benchmark, not in the product")
    for p in problems:
        print(p)
    if problems:
        print(f"{len(problems)} layout problem(s)")
        return 1
    print("layout: layers, file sizes and references are in order")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "."))
