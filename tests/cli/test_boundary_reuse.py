"""The secondary boundary term's reuse in `tandem optimize` ("restir": {"boundary": ...};
core/inverse/secondary_reuse_state.h), on tests/scenes/shape-lights-recover.json: a cube's vertex
positions under three small lights, 6 iterations. The log names the reuse; the run's parameters
differ from the same run without it (the reservoirs served); a run stopped at iteration 3 and
resumed ends with the first run's bits (parameters, metrics but timings, last image: the
checkpoint carries the reservoirs, their edge table, the grid's cell and the floor), and a resume
with another setting of the reuse is refused naming it. Bad settings are one line naming the
field; a config that optimizes no vertex positions is refused.

    test_boundary_reuse.py TANDEM
"""
import json
import pathlib
import subprocess
import sys
import tempfile

from test_shape_resume import outcome
from test_upsample_resume import run

ROOT = pathlib.Path(__file__).resolve().parents[2]
CONFIG = ROOT / "tests" / "scenes" / "shape-lights-recover.json"


def variant(tmp, name, **changes):
    """CONFIG with `changes` at the top level and its scene paths absolute, written to tmp/name."""
    config = json.load(open(CONFIG))
    config["scene"] = str(CONFIG.parent / config["scene"])
    config["target"]["scene"] = str(CONFIG.parent / config["target"]["scene"])
    config.update(changes)
    path = tmp / name
    path.write_text(json.dumps(config))
    return path


def refused(tandem, config, out, expect):
    p = subprocess.run([tandem, "optimize", str(config), "--out", str(out)], capture_output=True,
                       text=True)
    lines = p.stderr.strip().splitlines()
    if p.returncode == 0 or not lines or expect not in lines[-1]:
        sys.exit(f"{config.name}: expected a refusal naming '{expect}', got rc {p.returncode}:\n"
                 f"{p.stderr}")


def main():
    tandem = sys.argv[1]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        notes = run(tandem, CONFIG, tmp / "a")
        if "the secondary boundary term reuses light vertices" not in notes:
            sys.exit(f"the log does not name the boundary reuse:\n{notes}")
        plain = variant(tmp, "plain.json", restir={"adjoint": False, "boundary": False})
        run(tandem, plain, tmp / "plain")
        if outcome(tmp / "a", 6)[0] == outcome(tmp / "plain", 6)[0]:
            sys.exit("the run with boundary reuse ends where the run without it does: "
                     "the reservoirs did not serve")
        run(tandem, CONFIG, tmp / "b", "--until", "3")
        run(tandem, CONFIG, tmp / "b", "--resume")
        a, b = outcome(tmp / "a", 6), outcome(tmp / "b", 6)
        for what, x, y in zip(("parameters", "metrics", "last image"), a, b):
            if x != y:
                sys.exit(f"a run stopped at 3 and resumed: its {what} differ from the first run's")

        # a resume over another reuse setting is refused naming it (the checkpoint records them)
        fewer = variant(tmp, "fewer.json",
                        restir={"adjoint": False, "boundary": {"candidates": 2, "neighbours": 2}})
        run(tandem, fewer, tmp / "c", "--until", "3")
        more = variant(tmp, "more.json",
                       restir={"adjoint": False, "boundary": {"candidates": 4, "neighbours": 2}})
        p = subprocess.run([tandem, "optimize", str(more), "--out", str(tmp / "c"), "--resume"],
                           capture_output=True, text=True)
        if p.returncode == 0 or "restir.boundary.candidates changed since the checkpoint (2 -> 4)" \
                not in p.stderr:
            sys.exit(f"a resume with other boundary candidates: rc {p.returncode}\n{p.stderr}")

        bad = variant(tmp, "bad.json", restir={"adjoint": False, "boundary": {"neighbours": 99}})
        refused(tandem, bad, tmp / "bad", "restir: boundary: neighbours must be within")
        typo = variant(tmp, "typo.json", restir={"adjoint": False, "boundary": {"candidate": 4}})
        refused(tandem, typo, tmp / "typo", "candidate")
        kind = variant(tmp, "kind.json", restir={"adjoint": False, "boundary": 3})
        refused(tandem, kind, tmp / "kind", "boundary must be true, false or an object")
        albedo = variant(tmp, "albedo.json",
                         params={"wall.bsdf.reflectance": {"lr": 0.01}})
        refused(tandem, albedo, tmp / "albedo", "no vertex_positions parameter is optimized")
    print("boundary reuse in optimize: served, resume bit-identical, bad settings refused")


if __name__ == "__main__":
    main()
