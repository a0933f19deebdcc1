#!/usr/bin/env python3
"""Checks the repository's shape: no include runs from a lower layer to a higher one, no source
file outside tests/ is over 500 lines, nothing refers to files outside the repository, and every
repository path a file cites (core/..., kernels/..., tests/... with an extension) exists.

    python3 tests/repo/check_layout.py REPO_ROOT

Layers, lowest first; a file may include its own layer and those below it:
    kernels/shared < runtime < core/io < core/scene < core/bvh < core/render < core/inverse
    < bench < cli (the executable), python (the module; beside cli, above core), fuzz (the
    libFuzzer harnesses; beside cli)
Kernel sources (kernels/*.cl, kernels/path/*.h) include only kernels/, and call no transcendental
built-in (sin, cos, acos, atan2, exp, pow, ...): each implementation rounds those its own way, so
kernels use kernels/shared/det_math.h, which gives the same bits everywhere. Exits 1 listing every
violation.
"""
import os
import re
import sys

LAYERS = ["kernels", "runtime", "core/io", "core/scene", "core/bvh", "core/render", "core/inverse",
          "bench", "cli", "python", "fuzz"]
MAX_LINES = 500
SOURCE_EXT = (".cpp", ".h", ".cl", ".py", ".cmake", ".sh")
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')
TRANSCENDENTAL = re.compile(r"(?<![\w.])(?:native_|half_)?(sin|cos|tan|asin|acos|atan|atan2|sinh|cosh|"
                            r"tanh|exp|exp2|exp10|expm1|log|log2|log10|log1p|pow|powr|pown|rootn|"
                            r"cbrt|erf|erfc|tgamma|lgamma|sincos|sinpi|cospi|hypot)\s*\(")
DET_MATH = "kernels/shared/det_math.h"
OUTSIDE = re.compile(r"\.\./shared|papers/0\d\d|METHOD\.md|DESIGN\.md|RESTIR\.md|CONVENTIONS\.md")
CITED = re.compile(r"(?<![\w/.$])((?:core|kernels|runtime|tests|bench|cli|scripts|docs|scenes|cmake)/"
                   r"[A-Za-z0-9_./-]*[A-Za-z0-9_]\.(?:h|cpp|cl|py|md|sh|json|xml|cmake))\b")
# Files whose cited paths are not the repository's: synthetic trees of a test, and the dated
# history of the benchmark results (it names files as they were then).
CITES_EXEMPT = {"tests/runtime/test_program.cpp", "bench/RESULTS.md"}


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
            if not name.endswith(SOURCE_EXT):
                continue
            if not rel.startswith("tests/") and len(lines) > MAX_LINES:
                problems.append(f"{rel}: {len(lines)} lines (more than {MAX_LINES})")
            own = layer_of(rel)
            if own == 0 and rel != DET_MATH and name.endswith((".h", ".cl")):
                for number, line in enumerate(lines, 1):
                    code = line.split("//")[0]
                    m = TRANSCENDENTAL.search(code)
                    if m:
                        problems.append(f"{rel}:{number}: calls the built-in {m.group(1)}(); use "
                                        f"{DET_MATH} (the same bits on every device)")
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
    for p in problems:
        print(p)
    if problems:
        print(f"{len(problems)} layout problem(s)")
        return 1
    print("layout: layers, file sizes and references are in order")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "."))
