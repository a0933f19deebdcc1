#!/usr/bin/env python3
# Deterministic generator of Tandem's test and benchmark triangle meshes (standard library only).
# Usage: python3 scenes/gen_meshes.py OUTDIR   -- same output bytes on every run and platform.
import math
import os
import struct
import sys
from array import array

F32 = struct.Struct("<f")


def f32(x):
    """Round a Python float to the nearest float32 value (what the files store)."""
    return F32.unpack(F32.pack(x))[0]


def fmt(x):
    """ASCII float: '%.9g' of the float32 value round-trips exactly."""
    return "%.9g" % f32(x)


class Rng:
    """xorshift64* -- tiny local PRNG so the output never depends on global state."""

    def __init__(self, seed):
        self.s = (seed & 0xFFFFFFFFFFFFFFFF) or 1

    def below(self, n):
        x = self.s
        x ^= x >> 12
        x ^= (x << 25) & 0xFFFFFFFFFFFFFFFF
        x ^= x >> 27
        self.s = x
        return (((x * 0x2545F4914F6CDD1D) & 0xFFFFFFFFFFFFFFFF) >> 11) % n


# ----------------------------------------------------------------------------- writers

def write_atomic(outdir, name, data):
    path = os.path.join(outdir, name)
    tmp = os.path.join(outdir, ".%s.tmp%d" % (name, os.getpid()))
    try:
        with open(tmp, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


def ply_header(fmt_name, nv, nf, comment):
    return ("ply\nformat %s 1.0\ncomment %s\nelement vertex %d\n"
            "property float x\nproperty float y\nproperty float z\n"
            "element face %d\nproperty list uchar int vertex_indices\nend_header\n"
            % (fmt_name, comment, nv, nf)).encode("ascii")


def ply_binary(verts, faces, comment):
    xyz = array("f", [c for v in verts for c in v])
    if sys.byteorder == "big":
        xyz.byteswap()
    face = struct.Struct("<B3i")
    body = b"".join(face.pack(3, a, b, c) for a, b, c in faces)
    return ply_header("binary_little_endian", len(verts), len(faces), comment) + xyz.tobytes() + body


def ply_ascii(verts, faces, comment):
    lines = ["%s %s %s" % (fmt(x), fmt(y), fmt(z)) for x, y, z in verts]
    lines += ["3 %d %d %d" % f for f in faces]
    return ply_header("ascii", len(verts), len(faces), comment) + ("\n".join(lines) + "\n").encode("ascii")


def obj_text(verts, faces, comment):
    lines = ["# " + c for c in comment.split("\n")]
    lines += ["v %s %s %s" % (fmt(x), fmt(y), fmt(z)) for x, y, z in verts]
    lines += ["f %d %d %d" % (a + 1, b + 1, c + 1) for a, b, c in faces]
    return ("\n".join(lines) + "\n").encode("ascii")


# ----------------------------------------------------------------------------- meshes

def torus_knot(n_seg, n_ring, p=2, q=3, R=0.9, a=0.45, tube=0.13):
    """Closed tube around a (p,q) torus knot (trefoil); indexed, outward winding."""
    def curve(t):
        r = R + a * math.cos(q * t)
        return (r * math.cos(p * t), r * math.sin(p * t), a * math.sin(q * t))

    verts = []
    eps = 1e-4
    for i in range(n_seg):
        t = 2.0 * math.pi * i / n_seg
        c = curve(t)
        c0, c1 = curve(t - eps), curve(t + eps)
        T = norm(sub(c1, c0))
        N = norm(sub(c, scale(T, dot(c, T))))  # position minus its tangent part: never zero here
        B = cross(T, N)
        for j in range(n_ring):
            v = 2.0 * math.pi * j / n_ring
            cv, sv = math.cos(v) * tube, math.sin(v) * tube
            verts.append(tuple(c[k] + cv * N[k] + sv * B[k] for k in range(3)))
    faces = []
    for i in range(n_seg):
        i1 = (i + 1) % n_seg
        for j in range(n_ring):
            j1 = (j + 1) % n_ring
            a0, b0, c0, d0 = i * n_ring + j, i1 * n_ring + j, i1 * n_ring + j1, i * n_ring + j1
            faces.append((a0, d0, c0))
            faces.append((a0, c0, b0))
    return verts, faces


def grid_faces(base, nu, nv, wrap_u=False):
    """Two triangles per cell of a (nu x nv)-vertex lattice, row-major from `base`."""
    faces = []
    for i in range(nu - 1 + wrap_u):
        i1 = (i + 1) % nu
        for j in range(nv - 1):
            a0, b0 = base + i * nv + j, base + i1 * nv + j
            c0, d0 = base + i1 * nv + j + 1, base + i * nv + j + 1
            faces.append((a0, b0, c0))
            faces.append((a0, c0, d0))
    return faces


def degenerate_mesh():
    """Height field + sphere, then duplicates, coincident copies, zero-area and flipped tris."""
    rng = Rng(0xDE6E4E7A7E)
    verts, faces = [], []

    def unused(n):  # unreferenced vertices, interleaved between the real blocks
        for _ in range(n):
            verts.append(tuple((rng.below(2001) - 1000) / 250.0 for _ in range(3)))

    unused(16)
    n = 64  # height field z = 0.2 sin(3x) cos(2y) over [-1,1]^2, normals +z
    hf = len(verts)
    for i in range(n + 1):
        for j in range(n + 1):
            x, y = -1.0 + 2.0 * i / n, -1.0 + 2.0 * j / n
            verts.append((x, y, 0.2 * math.sin(3.0 * x) * math.cos(2.0 * y)))
    faces += grid_faces(hf, n + 1, n + 1)
    unused(32)
    stacks, slices, cz, r = 32, 64, 0.9, 0.45  # UV sphere above the height field, outward winding
    top = len(verts)
    verts.append((0.0, 0.0, cz + r))
    ring0 = len(verts)
    for s in range(1, stacks):
        th = math.pi * s / stacks
        for k in range(slices):
            ph = 2.0 * math.pi * k / slices
            verts.append((r * math.sin(th) * math.cos(ph), r * math.sin(th) * math.sin(ph), cz + r * math.cos(th)))
    bot = len(verts)
    verts.append((0.0, 0.0, cz - r))
    rv = lambda s, k: ring0 + (s - 1) * slices + k % slices
    for k in range(slices):
        faces.append((top, rv(1, k), rv(1, k + 1)))
        faces.append((bot, rv(stacks - 1, k + 1), rv(stacks - 1, k)))
        for s in range(1, stacks - 1):
            faces.append((rv(s, k), rv(s + 1, k), rv(s + 1, k + 1)))
            faces.append((rv(s, k), rv(s + 1, k + 1), rv(s, k + 1)))
    base = list(faces)
    pick = lambda: base[rng.below(len(base))]

    extra = [pick() for _ in range(len(base) // 10)]  # (a) exact duplicates, same indices
    for m in range(2000):  # (b) duplicates through coincident vertex copies (1-3 copied corners)
        tri, mask = list(pick()), m % 7 + 1
        for c in range(3):
            if mask >> c & 1:
                verts.append(verts[tri[c]])
                tri[c] = len(verts) - 1
        extra.append(tuple(tri))
    for m in range(1000):  # (c1) repeated index: a a b in all three positions
        a0, b0, _ = pick()
        extra.append(((a0, a0, b0), (a0, b0, a0), (b0, a0, a0))[m % 3])
    for m in range(500):  # (c2) all three indices identical
        extra.append((pick()[0],) * 3)
    col = lambda j: hf + (n // 2) * (n + 1) + j  # x == 0 column: z == 0 exactly -> exactly collinear
    for m in range(1000):  # (c3) three distinct collinear vertices, varied order
        k = 1 + rng.below(n // 2)
        j0 = rng.below(n + 1 - 2 * k)
        tri = (col(j0), col(j0 + k), col(j0 + 2 * k))
        extra.append((tri, (tri[0], tri[2], tri[1]), (tri[1], tri[0], tri[2]))[m % 3])
    for _ in range(2000):  # (d) reversed-winding duplicates
        a0, b0, c0 = pick()
        extra.append((a0, c0, b0))
    for i in range(len(extra) - 1, 0, -1):  # deterministic Fisher-Yates so kinds interleave
        j = rng.below(i + 1)
        extra[i], extra[j] = extra[j], extra[i]
    unused(64)
    return verts, base + extra


def far_slivers():
    """Thin slivers (aspect ~1e3-1e4, widths of 2-5 float32 ulps) offset by (1e4, 1e4, 1e4).
    Open cylinder of long strips (each split into 2 slivers) + shallow cone fan of 20k wedges."""
    o = 1.0e4
    verts, faces = [], []
    n_a, n_h, rc, hc = 4800, 3, 3.0, 8.0  # strip width 2*pi*3/4800 = 3.9e-3, length 16/3
    for i in range(n_a):
        ph = 2.0 * math.pi * i / n_a
        for k in range(n_h + 1):
            verts.append((o + rc * math.cos(ph), o + rc * math.sin(ph), o - hc + 2.0 * hc * k / n_h))
    faces += grid_faces(0, n_a, n_h + 1, wrap_u=True)
    n_f, rf, zf = 20000, 8.0, 9.0  # rim spacing 2*pi*8/20000 = 2.5e-3, wedge length 8
    apex = len(verts)
    verts.append((o, o, o + zf + 0.5))
    for i in range(n_f):
        ph = 2.0 * math.pi * i / n_f
        verts.append((o + rf * math.cos(ph), o + rf * math.sin(ph), o + zf))
    faces += [(apex, apex + 1 + i, apex + 1 + (i + 1) % n_f) for i in range(n_f)]
    return verts, faces


def tiny_mesh(bad):
    verts = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (1.0, 1.0, 0.5), (0.5, bad, 0.25)]
    return verts, [(0, 1, 2), (1, 3, 2), (2, 3, 4)]


# ----------------------------------------------------------------------------- vector helpers

def sub(a, b): return (a[0] - b[0], a[1] - b[1], a[2] - b[2])
def scale(a, s): return (a[0] * s, a[1] * s, a[2] * s)
def dot(a, b): return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
def cross(a, b): return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
def norm(a): return scale(a, 1.0 / math.sqrt(dot(a, a)))


# ----------------------------------------------------------------------------- main

def main(argv):
    if len(argv) != 2:
        sys.stderr.write("usage: python3 %s OUTDIR\n" % argv[0])
        return 2
    out = argv[1]
    os.makedirs(out, exist_ok=True)

    v, f = torus_knot(1024, 64)
    write_atomic(out, "knot.ply", ply_binary(v, f, "Tandem (2,3) torus-knot tube 1024x64, benchmark mesh"))
    v, f = torus_knot(64, 8)
    write_atomic(out, "knot_ascii.ply", ply_ascii(v, f, "Tandem (2,3) torus-knot tube 64x8"))
    write_atomic(out, "knot_small.obj", obj_text(v, f, "Tandem (2,3) torus-knot tube 64x8"))
    v, f = degenerate_mesh()
    write_atomic(out, "degenerate.obj", obj_text(
        v, f, "Tandem degeneracy stress: height field + sphere, duplicate / coincident-copy /\n"
              "zero-area / reversed-winding triangles appended, plus unreferenced vertices"))
    v, f = far_slivers()
    write_atomic(out, "far_slivers.ply", ply_binary(v, f, "Tandem thin slivers offset by 1e4 sharing edges"))
    for name, bad in (("bad_nan.obj", float("nan")), ("bad_inf.obj", float("inf"))):
        v, f = tiny_mesh(bad)
        write_atomic(out, name, obj_text(v, f, "Tandem invalid input: a vertex coordinate is %r" % bad))
    write_atomic(out, "empty.obj", b"# Tandem invalid input: no geometry at all\n")
    corrupt = ply_header("binary_little_endian", 1000, 1000, "Tandem invalid input: truncated body")
    corrupt += struct.pack("<6f", 0.0, 0.0, 0.0, 1.0, 0.0, 0.0) + b"\x00\x00\x80"  # 2.25 of 1000 vertices
    write_atomic(out, "corrupt.ply", corrupt)
    # Test images (not meshes, but the same kind of generated bad input): a 16x16 PFM reference
    # with one NaN texel, and a clean one. PFM: "PF", size, scale < 0 (little endian), rows
    # bottom to top.
    for name, nan in (("nan_16x16.pfm", True), ("grey_16x16.pfm", False)):
        px = [0.25] * (16 * 16 * 3)
        if nan:
            px[3 * (5 * 16 + 7) + 1] = float("nan")
        write_atomic(out, name, b"PF\n16 16\n-1.0\n" + struct.pack("<%df" % len(px), *px))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
