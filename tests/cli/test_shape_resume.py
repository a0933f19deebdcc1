"""Large Steps in `tandem optimize` (tests/scenes/shape-emitter-recover.json): a square light's
vertex positions, started 0.25 to the right of the target's, optimized through u = (I + 19 L) x.
The run converges (the parameter error at the end below a tenth of the first iteration's), the log
names the mesh's Large Steps, and a run stopped at iteration 20 and resumed ends with the first
run's bits: parameters, metrics (timings aside) and the last image (u and its moments are in the
checkpoint, and the resumed run's first image traces the checkpoint's positions).

    test_shape_resume.py TANDEM
"""
import csv
import json
import pathlib
import sys
import tempfile

from test_upsample_resume import run

ROOT = pathlib.Path(__file__).resolve().parents[2]


def outcome(folder):
    rows = list(csv.DictReader(open(folder / "metrics.csv")))
    metrics = [{k: v for k, v in row.items() if k != "seconds"} for row in rows]
    return json.load(open(folder / "params.json")), metrics, (folder / "iter_0040.exr").read_bytes()


def main():
    tandem = sys.argv[1]
    config = ROOT / "tests" / "scenes" / "shape-emitter-recover.json"
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        notes = run(tandem, config, tmp / "a")
        if "light.vertex_positions by Large Steps (lambda 19, 4 points)" not in notes:
            sys.exit(f"the log does not name the Large Steps:\n{notes}")
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
