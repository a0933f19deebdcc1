"""A grid's resolution schedule in `tandem optimize`: the job of scenes/media-plume-recover.json (the
plume's density from a flat start, 8 views, CV-PS, "upsample") at 16x16 for 12 iterations with
levels changing after iterations 2, 4 and 7, ends with the same bits when run again, and when
stopped at iteration 4 (--until: the checkpoint right after a level change) and resumed:
parameters, metrics (timings aside) and the last images. The log names each level.

    test_upsample_resume.py TANDEM
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
    images = [p.read_bytes() for p in sorted(folder.glob("views/*/iter_0012.exr"))]
    return json.load(open(folder / "params.json")), metrics, images


def main():
    tandem = sys.argv[1]
    job = json.load(open(ROOT / "scenes" / "media-plume-recover.json"))
    scene = str(ROOT / "scenes" / job["scene"])
    job.update(scene=scene, defines={"res": 16}, iterations=12, checkpoint_every=4,
               image_error_spp=2)
    job["target"].update(scene=scene, defines={"res": 16}, spp=16)
    job["params"]["plume.sigma_t"]["upsample"] = [2, 4, 7]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        config = tmp / "job.json"
        config.write_text(json.dumps(job))
        notes = run(tandem, config, tmp / "a")
        for line in ("resolution schedule 4x4x4 -> 8x8x8 after iteration 2", "CV-PS: fused",
                     "iteration 4: plume.sigma_t now 16x16x16",
                     "iteration 7: plume.sigma_t now 32x32x32"):
            if line not in notes:
                sys.exit(f"the log lacks '{line}':\n{notes}")
        run(tandem, config, tmp / "b")
        run(tandem, config, tmp / "c", "--until", "4")
        run(tandem, config, tmp / "c", "--resume")
        a, b, c = outcome(tmp / "a"), outcome(tmp / "b"), outcome(tmp / "c")
        if len(a[2]) != 8:
            sys.exit(f"expected the last images of 8 views, found {len(a[2])}")
        for name, other in (("a second run", b), ("a run stopped at 4 and resumed", c)):
            for what, x, y in zip(("parameters", "metrics", "last images"), a, other):
                if x != y:
                    sys.exit(f"{name}: its {what} differ from the first run's")
    print("grid schedule: rerun and resume across level changes bit-identical")


if __name__ == "__main__":
    main()
