"""Large Steps in `tandem optimize` (tests/scenes/shape-emitter-recover.json): a square light's
vertex positions, started 0.25 to the right of the target's, optimized through u = (I + 19 L) x.
The run converges (the parameter error at the end below a tenth of the first iteration's), the log
names the mesh's Large Steps, and a run stopped at iteration 20 and resumed ends with the first
run's bits: parameters, metrics (timings aside) and the last image (u and its moments are in the
checkpoint, and the resumed run's first image traces the checkpoint's positions). Each checkpoint
writes the mesh it reached (meshes/light.vertex_positions_iter_NNNN.ply): the last one holds the
final positions of params.json, bit for bit, and the square's two triangles.

    test_shape_resume.py TANDEM
"""
import csv
import json
import pathlib
import struct
import sys
import tempfile

from test_upsample_resume import run

ROOT = pathlib.Path(__file__).resolve().parents[2]


def outcome(folder, last=40):
    """The run's final parameters, its metrics without timings, and its image of iteration `last`."""
    rows = list(csv.DictReader(open(folder / "metrics.csv")))
    metrics = [{k: v for k, v in row.items() if k != "seconds"} for row in rows]
    return (json.load(open(folder / "params.json")), metrics,
            (folder / f"iter_{last:04d}.exr").read_bytes())


def ply_mesh(path):
    """The vertices (x y z floats) and faces of a binary PLY that tandem wrote."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode().split("\n")
    count = {l.split()[1]: int(l.split()[2]) for l in header if l.startswith("element")}
    nv, nf = count["vertex"], count["face"]
    xyz = list(struct.unpack_from(f"<{3 * nv}f", data, end))
    at = end + 12 * nv
    faces = [struct.unpack_from("<B3I", data, at + 13 * f)[1:] for f in range(nf)]
    return xyz, faces


def main():
    tandem = sys.argv[1]
    config = ROOT / "tests" / "scenes" / "shape-emitter-recover.json"
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        notes = run(tandem, config, tmp / "a")
        if "light.vertex_positions by Large Steps (lambda 19, 4 points)" not in notes:
            sys.exit(f"the log does not name the Large Steps:\n{notes}")
        xyz, faces = ply_mesh(tmp / "a" / "meshes" / "light.vertex_positions_iter_0040.ply")
        final = json.load(open(tmp / "a" / "params.json"))["light.vertex_positions"]
        if xyz != [struct.unpack("<f", struct.pack("<f", v))[0] for v in final] or len(faces) != 2:
            sys.exit(f"meshes/light.vertex_positions_iter_0040.ply: {xyz} {faces}, not {final}")
        if not (tmp / "a" / "meshes" / "light.vertex_positions_iter_0020.ply").exists():
            sys.exit("no mesh written at the checkpoint of iteration 20")
        run(tandem, config, tmp / "b", "--until", "20")
        run(tandem, config, tmp / "b", "--resume")
        a, b = outcome(tmp / "a"), outcome(tmp / "b")
        for what, x, y in zip(("parameters", "metrics", "last image"), a, b):
            if x != y:
                sys.exit(f"a run stopped at 20 and resumed: its {what} differ from the first run's")
        first, last = float(a[1][0]["param_error"]), float(a[1][-1]["param_error"])
        if not last < 0.1 * first:
            sys.exit(f"parameter error {first} -> {last}: not below a tenth")
    print(f"large steps: parameter error {first:.4f} -> {last:.4f}; resume bit-identical")


if __name__ == "__main__":
    main()
