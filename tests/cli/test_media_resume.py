"""Media in `tandem optimize`: the job of scenes/media-cube-recover.json (the smoke's extinction,
the fused CV-PS, L1) at 32x32 for 40 iterations ends with the same bits when run again, and when stopped at
iteration 20 (--until) and resumed: parameters, metrics (timings aside) and the last image.

    test_media_resume.py TANDEM
"""
import csv
import json
import pathlib
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[2]


def run(tandem, config, out, *extra):
    r = subprocess.run([tandem, "optimize", str(config), "--out", str(out), *extra],
                       capture_output=True, text=True)
    if r.returncode:
        sys.exit(f"tandem optimize {' '.join(extra)} failed:\n{r.stderr}")
    return r.stderr


def outcome(folder):
    rows = list(csv.DictReader(open(folder / "metrics.csv")))
    metrics = [{k: v for k, v in row.items() if k != "seconds"} for row in rows]
    return (json.load(open(folder / "params.json")), metrics,
            (folder / "iter_0040.exr").read_bytes())


def main():
    tandem = sys.argv[1]
    job = json.load(open(ROOT / "scenes" / "media-cube-recover.json"))
    scene = str(ROOT / "scenes" / job["scene"])
    job.update(scene=scene, defines={"res": 32}, iterations=40, checkpoint_every=10,
               image_error_spp=4)
    job["target"].update(scene=scene, defines={"res": 32}, spp=64)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        config = tmp / "job.json"
        config.write_text(json.dumps(job))
        notes = run(tandem, config, tmp / "a")
        if "CV-PS: fused" not in notes:
            sys.exit(f"the control variate's plan is not the fused CV-PS:\n{notes}")
        run(tandem, config, tmp / "b")
        run(tandem, config, tmp / "c", "--until", "20")
        run(tandem, config, tmp / "c", "--resume")
        a, b, c = outcome(tmp / "a"), outcome(tmp / "b"), outcome(tmp / "c")
        for name, other in (("a second run", b), ("a run stopped at 20 and resumed", c)):
            for what, x, y in zip(("parameters", "metrics", "last image"), a, other):
                if x != y:
                    sys.exit(f"{name}: its {what} differ from the first run's")
    print("media job: rerun and resume bit-identical")


if __name__ == "__main__":
    main()
