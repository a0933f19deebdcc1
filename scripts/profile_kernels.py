#!/usr/bin/env python3
"""Where the kernel time goes on PoCL: perf samples split by what the path was doing.

    scripts/profile_kernels.py [--freq HZ] [--top N] [--json] -- build/tandem render scenes/cbox.xml ...

Runs the command under `perf record` with TANDEM_KERNEL_DEBUG=1, which builds the kernels with
line tables (-g; the generated code is the same). PoCL loads each kernel as a shared object from
its cache; every sample that lands in one is mapped back to its inline chain with addr2line. The
innermost frame whose file owns a category decides it (generic helpers, such as the vector algebra
of sampling.h, count for their caller):

  traversal (closest hit)   kernels/shared/bvh_traverse.h, bvh4_traverse.h, bvh8_traverse.h, bvh_tri4.h,
                            under a closest hit
  traversal (shadow rays)   the same files under an any-hit query
  RNG                       kernels/shared/rng.h, kernels/path/random.h
  transcendentals           kernels/shared/det_math.h (the project's sin, cos, acos, atan2)
  light sampling and NEE    kernels/path/nee.h, emission.h, restir.h, shared/envmap.h, reservoir.h
  BSDF and textures         bsdfs.h, microfacet.h, fresnel.h, textures.h, plastic_table.h,
                            bsdf_grad.h, path/continuation.h, path/interaction.h
  adjoint accumulation      fixed_point.h, path/adjoint.h, path/replay.h
  control variate           kernels/shared/cv.h
  unattributed              no line table entry (e.g. the work-group loop's own prologue)
  path loop and camera      the estimator itself (primal.h, two_state.h, camera, kernel bodies)

Samples outside the kernels (the loader, the driver, the host) are reported as one line. Needs
Debian's linux-perf and binutils; perf must be allowed to sample the process (perf_event_paranoid
<= 2 for one's own processes).

The line tables of heavily inlined code can misplace samples: on indirect-room this script gave
texture_eval 15.5 %, while a kernel copy whose texture lookups return a constant ran no faster
beyond the machine's noise (a removal probe: a copy of kernels/ through TANDEM_KERNEL_DIR). Check a share by removing the
work before acting on it.
"""
import argparse
import collections
import difflib
import json
import os
import re
import subprocess
import sys
import tempfile

TOP_KEPT = 40  # hottest functions kept in the result

# The file that owns a sample: the innermost frame of its inline chain whose file is listed here.
# Generic helpers (vector algebra, sampling warps in sampling.h) belong to whoever calls them.
OWNERS = {
    "bvh_traverse.h": "traversal", "bvh4_traverse.h": "traversal", "bvh8_traverse.h": "traversal",
    "bvh_tri4.h": "traversal",
    "rng.h": "RNG", "random.h": "RNG",
    "det_math.h": "transcendentals",
    "nee.h": "light sampling and NEE", "emission.h": "light sampling and NEE",
    "restir.h": "light sampling and NEE", "envmap.h": "light sampling and NEE",
    "reservoir.h": "light sampling and NEE",
    "bsdfs.h": "BSDF and textures", "microfacet.h": "BSDF and textures",
    "fresnel.h": "BSDF and textures", "textures.h": "BSDF and textures",
    "plastic_table.h": "BSDF and textures", "bsdf_grad.h": "BSDF and textures",
    "continuation.h": "BSDF and textures", "interaction.h": "BSDF and textures",
    "fixed_point.h": "adjoint accumulation", "adjoint.h": "adjoint accumulation",
    "replay.h": "adjoint accumulation", "cv.h": "control variate",
}
ANY_HIT = ("intersect_any", "leaf_any", "trace_any")


def categorize(chain):
    """chain: [(function, file basename)], innermost first."""
    for _, f in chain:
        owner = OWNERS.get(f)
        if owner == "traversal":
            shadow = any(a in func for func, _ in chain for a in ANY_HIT)
            return "traversal (shadow rays)" if shadow else "traversal (closest hit)"
        if owner:
            return owner
    return "path loop and camera"


def load_segments(path):
    """PT_LOAD segments of an ELF file as (offset, vaddr, filesz)."""
    out = subprocess.run(["readelf", "-lW", path], capture_output=True, text=True, check=True)
    segs = []
    for line in out.stdout.splitlines():
        parts = line.split()
        if parts and parts[0] == "LOAD":
            segs.append((int(parts[1], 16), int(parts[2], 16), int(parts[4], 16)))
    return segs


def file_to_vaddr(segs, off):
    for o, v, size in segs:
        if o <= off < o + size:
            return off - o + v
    return None


def disassemble(path):
    """{function: [(address, normalised instruction)]} from objdump."""
    out = subprocess.run(["objdump", "-d", "--no-show-raw-insn", path], capture_output=True,
                         text=True, check=True).stdout
    funcs, cur = {}, None
    for line in out.splitlines():
        m = re.match(r"^([0-9a-f]+) <(.+)>:$", line)
        if m:
            cur = funcs.setdefault(m.group(2), [])
            continue
        m = re.match(r"^\s+([0-9a-f]+):\s+(.*)$", line)
        if m and cur is not None:
            # Branch targets, symbol offsets, rip-relative and stack displacements and the
            # register allocation differ between copies of the same code: the instruction's shape
            # is what is aligned (95 % of the render kernel's instructions match).
            text = re.sub(r"\b[0-9a-f]+ <[^>]*>", "T", m.group(2))
            text = re.sub(r"#.*$", "", text)
            text = re.sub(r"-?0x[0-9a-f]+\(%(rip|rsp)", r"D(%\1", text)
            text = re.sub(r"%[xyz]mm[0-9]+", "%v", text)
            text = re.sub(r"%(r[0-9]+[dwb]?|[re]?[abcd]x|[re]?[sd]i|[re]?bp|[abcd]l)\b", "%g", text)
            cur.append((int(m.group(1), 16), " ".join(text.split())))
    return funcs


def workgroup_map(path):
    """Address in a work-group function -> the matching address in the kernel function.

    PoCL compiles each kernel twice into the object: `_pocl_kernel_K`, which keeps the line
    tables, and `_pocl_kernel_K_workgroup` (and `_fast`), the work-item loop around a copy of the
    same body, which runs but has none. The copies are aligned instruction by instruction
    (difflib over the normalised text); an unmatched instruction takes the nearest matched one
    before it.
    """
    funcs = disassemble(path)
    mapping, matched_total, total = {}, 0, 0
    for name, body in funcs.items():
        for suffix in ("_workgroup_fast", "_workgroup"):
            if name.endswith(suffix) and name[: -len(suffix)] in funcs:
                base = funcs[name[: -len(suffix)]]
                sm = difflib.SequenceMatcher(None, [t for _, t in body], [t for _, t in base],
                                             autojunk=False)
                matched = [None] * len(body)
                for blk in sm.get_matching_blocks():
                    for k in range(blk.size):
                        matched[blk.a + k] = base[blk.b + k][0]
                matched_total += sum(m is not None for m in matched)
                total += len(body)
                last = None  # the prologue before the first match stays unattributed
                for (addr, _), m in zip(body, matched):
                    last = m if m is not None else last
                    if last is not None:
                        mapping[addr] = last
                break
    return mapping, (matched_total / total if total else 1.0)


def inline_chains(path, addrs):
    """addr -> [(function, file basename), ...], innermost first (addr2line -i)."""
    inp = "".join("%x\n" % a for a in addrs)
    out = subprocess.run(["addr2line", "-e", path, "-f", "-i", "-a"], input=inp,
                         capture_output=True, text=True, check=True).stdout.splitlines()
    chains, cur, i = {}, None, 0
    while i < len(out):
        line = out[i]
        if line.startswith("0x"):
            cur = int(line, 16)
            chains[cur] = []
            i += 1
            continue
        func, loc = line, out[i + 1] if i + 1 < len(out) else "??:0"
        chains[cur].append((func, os.path.basename(loc.split(":")[0])))
        i += 2
    return chains


def command_after_dashes(ap, a, verb):
    """The command given after `--` (argparse REMAINDER in a.command); an argparse error if none."""
    cmd = a.command[1:] if a.command[:1] == ["--"] else a.command
    if not cmd:
        ap.error("no command to %s (give it after --)" % verb)
    return cmd


def debug_environment(tmp):
    """The environment for a command whose kernels must carry line tables: TANDEM_KERNEL_DEBUG=1
    and fresh caches under tmp (a kernel object PoCL or Tandem cached from a build without -g
    would be reused as it is, without line tables)."""
    return dict(os.environ, TANDEM_KERNEL_DEBUG="1", TANDEM_CACHE_DIR=os.path.join(tmp, "tc"),
                POCL_CACHE_DIR=os.path.join(tmp, "pc"))


def last_error(proc):
    """The last line a failed subprocess wrote to stderr, or its exit status."""
    return (proc.stderr.strip().splitlines()[-1:] or ["exit status %d" % proc.returncode])[0]


MMAP = re.compile(r"PERF_RECORD_MMAP2? .*\[(0x[0-9a-f]+)\((0x[0-9a-f]+)\) @ (0x[0-9a-f]+|0) .*\]: "
                  r"\S+ (\S+\.so)$")


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--freq", type=int, default=4000, help="samples per second (default 4000)")
    ap.add_argument("--top", type=int, default=0,
                    help="also list the N hottest innermost functions (at most %d)" % TOP_KEPT)
    ap.add_argument("--json", action="store_true", help="print the shares as JSON")
    ap.add_argument("command", nargs=argparse.REMAINDER, help="-- then the command to profile")
    a = ap.parse_args()
    cmd = command_after_dashes(ap, a, "profile")

    with tempfile.TemporaryDirectory() as tmp:
        data = os.path.join(tmp, "perf.data")
        env = debug_environment(tmp)
        rec = subprocess.run(["perf", "record", "-F", str(a.freq), "-o", data, "--"] + cmd,
                             env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        if rec.returncode != 0:
            sys.exit("profile_kernels: the command failed under perf: " + last_error(rec))
        script = subprocess.run(["perf", "script", "-i", data, "--show-mmap-events", "-F", "ip,dso"],
                                capture_output=True, text=True, check=True).stdout
        result = analyse(script, os.path.realpath(env["POCL_CACHE_DIR"]))
    report(a, result)


def analyse(script, kernel_dir):
    """Shares of the samples in `perf script` output, while the kernel objects still exist."""
    maps = []  # (start, end, pgoff, path) of the kernels' shared objects
    samples = collections.Counter()
    other = 0
    for line in script.splitlines():
        m = MMAP.search(line)
        if m:
            path = m.group(4)
            if os.path.realpath(path).startswith(kernel_dir):
                start, size = int(m.group(1), 16), int(m.group(2), 16)
                maps.append((start, start + size, int(m.group(3), 16), path))
            continue
        parts = line.split(None, 1)
        if len(parts) != 2 or not re.fullmatch(r"[0-9a-f]+", parts[0]):
            continue
        ip, dso = int(parts[0], 16), parts[1].strip()[1:-1]
        # The latest mapping of the sample's own object: PoCL maps and unmaps kernels as it goes.
        hit = next((mp for mp in reversed(maps) if mp[3] == dso and mp[0] <= ip < mp[1]), None)
        if hit is None:
            other += 1
            continue
        samples[(hit[3], ip - hit[0] + hit[2])] += 1

    per_file = collections.defaultdict(dict)
    for (path, off), n in samples.items():
        per_file[path][off] = n
    shares = collections.Counter()
    match_rates = {}
    kernels = collections.Counter()
    lines = collections.Counter()
    for path, offs in per_file.items():
        segs = load_segments(path)
        wg, rate = workgroup_map(path)
        kernel = os.path.basename(path)[:-3]
        match_rates[kernel] = rate
        vaddrs = {}
        for off in offs:
            v = file_to_vaddr(segs, off)
            in_workgroup = v is not None and v in wg
            vaddrs[off] = wg[v] if in_workgroup else v
        chains = inline_chains(path, sorted(v for v in vaddrs.values() if v is not None))
        for off, n in offs.items():
            chain = chains.get(vaddrs[off])
            kernels[kernel] += n
            if not chain or chain[0][1] in ("", "??"):  # no line table entry
                shares["unattributed"] += n
                lines["unattributed"] += n
                continue
            shares[categorize(chain)] += n
            owner_file = next((f for _, f in chain if f in OWNERS), None)
            where = "%s (%s)" % (chain[0][1], chain[0][0])
            lines[where if owner_file in (None, chain[0][1]) else where + " in " + owner_file] += n
    total_kernel = sum(shares.values())
    total = total_kernel + other
    if total_kernel == 0:
        sys.exit("profile_kernels: no samples landed in a PoCL kernel")
    return {
        "samples": total,
        "kernel_share": total_kernel / total,
        "kernels": {k: n / total_kernel for k, n in kernels.most_common()},
        "categories": {k: n / total_kernel for k, n in shares.most_common()},
        "alignment_match": match_rates,
        "top": [[k, n / total_kernel] for k, n in lines.most_common(TOP_KEPT)],
    }


def report(a, result):
    if a.json:
        print(json.dumps(result, indent=2))
        return
    print("%d samples, %.1f %% in kernels (%s)" % (
        result["samples"], 100.0 * result["kernel_share"],
        ", ".join("%s %.1f %%" % (k, 100.0 * v) for k, v in result["kernels"].items())))
    print("work-group code matched to the kernel's line tables: " + ", ".join(
        "%s %.1f %%" % (k, 100.0 * v) for k, v in sorted(result["alignment_match"].items())))
    print("| share of kernel time | category |")
    print("|---|---|")
    for k, v in result["categories"].items():
        print("| %.1f %% | %s |" % (100.0 * v, k))
    if a.top:
        print("\nhottest innermost functions:")
        for k, share in result["top"][: a.top]:
            print("  %5.1f %%  %s" % (100.0 * share, k))


if __name__ == "__main__":
    main()
