#!/usr/bin/env python3
"""Exact instruction counts of one PoCL kernel, from Valgrind's callgrind: where timings on a shared
machine move by 10-20 %, the count of executed instructions is the same in every run, so a change
to a kernel that keeps the image's bits can be weighed exactly (the work is the same).

    scripts/count_instructions.py [--kernel render_pass] [--top N] [--blocks N] [--json] -- build/tandem render ...

Runs the command once natively with TANDEM_KERNEL_DEBUG=1 (line tables; the same machine code) and
fresh kernel caches, then again under `valgrind --tool=callgrind` on the cached kernel objects, and
counts the instructions executed in the kernel's work-group functions (PoCL's
`_pocl_kernel_K_workgroup*`). Prints the total, the share of stack loads and stores (spills), and
the split by what the path was doing and by innermost inlined function, as scripts/profile_kernels.py
does for time (the same categories and the same mapping of the work-group copy onto the kernel's
line tables; that mapping can misplace a few instructions, the total cannot). With --blocks N, also
the N hottest basic blocks in machine code, each with the inlined functions it comes from.

Instructions are not time: a division or a cache miss costs more than a move. Count a change to
find and size it, then time it. Needs Debian's valgrind,
binutils and the tools scripts/profile_kernels.py needs; a small render (64², a few samples) is
enough, about half a minute.
"""
import argparse
import collections
import json
import os
import re
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import profile_kernels as pk  # noqa: E402  (categories and the work-group mapping)


def read_callgrind(path, kernel):
    """{address: instructions} of the kernel's work-group functions, and the object they are in.
    The file is written with --compress-pos=no --compress-strings=no: each cost line is
    "address line count"; the line after a calls= line is the call's inclusive cost, skipped."""
    counts, obj, cur_obj, cur_fn, after_call = collections.Counter(), None, None, None, False
    prefix = "_pocl_kernel_%s_workgroup" % kernel
    with open(path) as f:
        for line in f:
            if line.startswith("ob="):
                cur_obj = line[3:].strip()
            elif line.startswith("fn="):
                cur_fn = line[3:].strip()
            elif line.startswith("calls="):
                after_call = True
            elif line.startswith("0x"):
                if after_call:
                    after_call = False
                elif cur_fn and cur_fn.startswith(prefix):
                    parts = line.split()
                    counts[int(parts[0], 16)] += int(parts[-1])
                    obj = cur_obj
    return counts, obj


def hottest_blocks(counts, text, n):
    """The n runs of machine code that execute the most instructions, as (executions, addresses):
    a run is consecutive instructions with one execution count, cut after a jump or a return (a
    basic block, as far as the counts tell blocks apart)."""
    blocks, run = [], []
    for x in sorted(text):
        if run and counts.get(x, 0) != counts.get(run[-1], 0):
            blocks.append(run)
            run = []
        run.append(x)
        if text[x].startswith(("j", "ret")):
            blocks.append(run)
            run = []
    blocks.append(run)
    blocks = [b for b in blocks if b and counts.get(b[0], 0) > 0]
    blocks.sort(key=lambda b: -counts[b[0]] * len(b))
    return [(counts[b[0]], b) for b in blocks[:n]]


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--kernel", default="render_pass", help="kernel name (default render_pass)")
    ap.add_argument("--top", type=int, default=15, help="innermost functions listed (default 15)")
    ap.add_argument("--blocks", type=int, default=0,
                    help="also list the N hottest basic blocks with their machine code")
    ap.add_argument("--json", action="store_true", help="print the counts as JSON")
    ap.add_argument("command", nargs=argparse.REMAINDER, help="-- then the command to count")
    a = ap.parse_args()
    cmd = pk.command_after_dashes(ap, a, "count")

    with tempfile.TemporaryDirectory() as tmp:
        env = pk.debug_environment(tmp)
        # Natively first: the kernels are compiled outside Valgrind (which would take minutes).
        first = subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                               text=True)
        if first.returncode != 0:
            sys.exit("count_instructions: the command failed: " + pk.last_error(first))
        out = os.path.join(tmp, "callgrind.out")
        run = subprocess.run(["valgrind", "--tool=callgrind", "--dump-instr=yes",
                              "--compress-pos=no", "--compress-strings=no",
                              "--callgrind-out-file=" + out] + cmd,
                             env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        if run.returncode != 0:
            sys.exit("count_instructions: the command failed under valgrind: " + pk.last_error(run))
        counts, obj = read_callgrind(out, a.kernel)
        if not counts:
            sys.exit("count_instructions: no instructions of kernel '%s' were executed" % a.kernel)

        # Callgrind reports addresses as the object's virtual addresses.
        mapping, matched = pk.workgroup_map(obj)
        chains = pk.inline_chains(obj, sorted(set(mapping[x] for x in counts if x in mapping)))
        text = {}
        for line in subprocess.run(["objdump", "-d", "--no-show-raw-insn", obj],
                                   capture_output=True, text=True, check=True).stdout.splitlines():
            m = re.match(r"^\s+([0-9a-f]+):\s+(.*)$", line)
            if m:
                text[int(m.group(1), 16)] = m.group(2)

    total = sum(counts.values())
    stack_loads = sum(c for x, c in counts.items()
                      if re.search(r"\(%rsp\),", text.get(x, "")))
    stack_stores = sum(c for x, c in counts.items()
                       if "(%rsp)" in text.get(x, "") and not re.search(r"\(%rsp\),", text.get(x, "")))
    by_category, by_function = collections.Counter(), collections.Counter()
    for x, c in counts.items():
        chain = chains.get(mapping.get(x), [])
        by_category[pk.categorize(chain) if chain else "unattributed"] += c
        if chain:
            by_function["%s (%s)" % (chain[0][1], chain[0][0])] += c
    result = {"kernel": a.kernel, "instructions": total, "stack_loads": stack_loads,
              "stack_stores": stack_stores, "workgroup_code_matched": matched,
              "categories": dict(by_category.most_common()),
              "functions": dict(by_function.most_common(a.top))}
    blocks = hottest_blocks(counts, text, a.blocks)

    def where(x):  # the inlined functions at address x, innermost first
        return [f for f, _ in chains.get(mapping.get(x), [])]

    result["blocks"] = [{"executions": c, "instructions": len(b), "address": hex(b[0]),
                         "functions": where(b[0])[:4]} for c, b in blocks]
    if a.json:
        print(json.dumps(result, indent=2))
        return
    print("%s: %s instructions; stack loads %.1f %%, stores %.1f %%" %
          (a.kernel, format(total, ","), 100.0 * stack_loads / total, 100.0 * stack_stores / total))
    print("| share | instructions | category |\n|---|---|---|")
    for k, v in by_category.most_common():
        print("| %.1f %% | %s | %s |" % (100.0 * v / total, format(v, ","), k))
    if a.top:
        print("innermost functions:")
        for k, v in by_function.most_common(a.top):
            print("  %5.1f %%  %s" % (100.0 * v / total, k))
    for c, b in blocks:
        print("=== %s executions x %d instructions = %.2f %%   %s" %
              (format(c, ","), len(b), 100.0 * c * len(b) / total, " < ".join(where(b[0])[:4])))
        for x in b:
            print("  %6x  %-60s %s" % (x, text[x][:60], (where(x) or [""])[0]))


if __name__ == "__main__":
    main()
