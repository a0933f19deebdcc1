#!/usr/bin/env python3
"""`mpirun -np N tandem optimize` (cli/mpi_job.h, core/inverse/ranks.h) on localhost, against the
same run as one process, on scenes/globe.xml's eight sensors at 16x16 (CV-PS, and CV-PS with
ReSTIR on the adjoint, so that the control variates' statistics and the reservoirs live on the
ranks that own their views):

- 2 and 3 ranks give the one process's outputs: every image of views/*/ the same stored words
  (tandem-imgcmp), params.json and the other files the same bytes, metrics.csv the same but for
  its wall-clock column, the checkpoints the same but for their wall-clock section (each view's
  state included: rank 0 gathers it from the rank that keeps it).
- A 2-rank run stopped at a checkpoint (--until 4) resumes on 1 rank, and one stopped at
  --until 8 on 3 ranks, to the uninterrupted run's outputs.
- A rank killed (SIGKILL at the start of iteration 6: TANDEM_KILL_AT on rank 1 alone) ends the
  job with a nonzero status and a line that names the rank; the last checkpoint resumes (on 2
  ranks) to the uninterrupted run's outputs.
- More ranks than the batch's views: an error line per rank, each whole, a nonzero status, no
  hang. Ranks that would start from different points (rank 1 sees an empty folder where rank 0
  resumes a checkpoint) stop with an error, and the checkpoint still resumes.
- `tandem devices` lists each rank's device; `tandem render` refuses to run across ranks.

Skipped (exit 77) where tandem was built without MPI or no launcher is found.

    python3 tests/cli/test_mpi.py TANDEM_BINARY IMGCMP_BINARY MPIEXEC
"""

import importlib.util
import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import unittest

ROOT = pathlib.Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("views", ROOT / "tests" / "cli" / "test_views.py")
views = importlib.util.module_from_spec(spec)
spec.loader.exec_module(views)
TANDEM = MPIEXEC = None  # set from argv
# Open MPI refuses root without these (CI runs as root); --oversubscribe: more ranks than cores
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1")
TIMEOUT = 240  # a hang is a failure, not a stuck suite


def mpirun(ranks, *command, env=None, rank1_env=None):
    """`command` (tandem's arguments) on `ranks` ranks; rank1_env: variables for rank 1 alone."""
    prefix = [MPIEXEC, "--oversubscribe", "-np", str(ranks)]
    if rank1_env:  # a shell per rank that sets them on rank 1 only (OMPI_COMM_WORLD_RANK)
        sets = " ".join(f"{k}={v}" for k, v in rank1_env.items())
        script = f'if [ "$OMPI_COMM_WORLD_RANK" = 1 ]; then export {sets}; fi; exec "$@"'
        return subprocess.run(prefix + ["sh", "-c", script, "sh", TANDEM, *command],
                              capture_output=True, text=True, env=env or ENV, timeout=TIMEOUT)
    return subprocess.run(prefix + [TANDEM, *command], capture_output=True, text=True,
                          env=env or ENV, timeout=TIMEOUT)


def optimize(ranks, config, out, *extra, **kw):
    args = ["optimize", str(config), "--out", str(out), *extra]
    if ranks == 1:
        return subprocess.run([TANDEM, *args], capture_output=True, text=True, timeout=TIMEOUT)
    return mpirun(ranks, *args, **kw)


class Ranks(unittest.TestCase):
    """Per variant: "one", the run as one process, the reference of every comparison."""

    VARIANTS = {"cv": views.base_config(batch=4),
                "restir": views.base_config(batch=4, restir={"adjoint": True})}

    @classmethod
    def setUpClass(cls):
        cls.work = pathlib.Path(tempfile.mkdtemp(prefix="tandem-mpi-"))
        cls.addClassCleanup(shutil.rmtree, cls.work, ignore_errors=True)
        for variant, config in cls.VARIANTS.items():
            (cls.work / f"{variant}.json").write_text(json.dumps(config))
            r = optimize(1, cls.config(variant), cls.work / variant / "one")
            assert r.returncode == 0, r.stderr

    @classmethod
    def config(cls, variant):
        return cls.work / f"{variant}.json"

    def run_into(self, variant, name, ranks, *extra, source=None, **kw):
        out = self.work / variant / name
        shutil.rmtree(out, ignore_errors=True)
        if source:
            shutil.copytree(self.work / variant / source, out)
        return out, optimize(ranks, self.config(variant), out, *extra, **kw)

    def assert_same(self, variant, out, what):
        self.assertEqual(views.differences(self.work / variant / "one", out), [], what)

    def test_two_and_three_ranks_equal_one_process(self):
        for variant in self.VARIANTS:
            for ranks in (2, 3):
                what = f"{variant}, {ranks} ranks"
                out, r = self.run_into(variant, f"ranks-{ranks}", ranks)
                self.assertEqual(r.returncode, 0, f"{what}: {r.stderr}")
                self.assertIn(f"tandem optimize: {ranks} ranks; view v renders on rank v mod "
                              f"{ranks}: rank 0 on ", r.stderr, what)
                self.assertEqual(r.stdout.count("iterations in"), 1, what)  # rank 0 reports
                self.assert_same(variant, out, what)

    def test_resume_on_another_number_of_ranks(self):
        for variant in self.VARIANTS:
            for until, first, then in ((4, 2, 1), (8, 2, 3)):
                what = f"{variant}: --until {until} on {first} ranks, resumed on {then}"
                out, r = self.run_into(variant, f"until-{until}", first, "--until", str(until))
                self.assertEqual(r.returncode, 0, f"{what}: {r.stderr}")
                r = optimize(then, self.config(variant), out, "--resume")
                self.assertEqual(r.returncode, 0, f"{what}: {r.stderr}")
                self.assert_same(variant, out, what)

    def test_a_killed_rank_ends_the_job_and_its_checkpoint_resumes(self):
        variant = "restir"
        out, r = self.run_into(variant, "killed", 2, rank1_env={"TANDEM_KILL_AT": "iteration:6"})
        self.assertNotEqual(r.returncode, 0, r.stderr)
        # Open MPI's launcher names the rank and the signal
        self.assertRegex(r.stderr, r"rank 1 .*(signal 9|Killed)", r.stderr)
        self.assertFalse((out / "params.json").exists())  # it did not finish
        r = optimize(2, self.config(variant), out, "--resume")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assert_same(variant, out, "killed at iteration 6 on rank 1, resumed on 2 ranks")

    def test_more_ranks_than_the_batch_is_an_error(self):
        config = self.work / "small-batch.json"
        config.write_text(json.dumps(views.base_config(batch=2, iterations=2)))
        out = self.work / "small-batch"
        r = optimize(3, config, out)
        self.assertNotEqual(r.returncode, 0)
        lines = views.kr.error_lines(r.stderr)
        self.assertTrue(lines, r.stderr)
        for line in lines:  # each rank's line whole (one write each), naming its rank
            self.assertRegex(line, r"^tandem: error: rank [0-2] of 3: ")
            self.assertTrue(line.endswith(f"{config}: 3 ranks for a batch of 2 views: run at "
                                          "most 2 (mpirun -np)"), line)

    def test_the_ranks_must_resume_from_one_folder(self):
        # rank 0 resumes a checkpoint at iteration 4, rank 1 sees an empty folder (as a node
        # without the shared folder would): one error, not mismatched exchanges
        variant = "cv"
        out, r = self.run_into(variant, "agree", 2, "--until", "4")
        self.assertEqual(r.returncode, 0, r.stderr)
        elsewhere = self.work / "agree-elsewhere"
        script = ('out="$1"; shift; if [ "$OMPI_COMM_WORLD_RANK" = 1 ]; then out="$1"; fi; '
                  'shift; exec "$@" --out "$out" --resume')
        r = subprocess.run([MPIEXEC, "--oversubscribe", "-np", "2", "sh", "-c", script, "sh",
                            str(out), str(elsewhere), TANDEM, "optimize", str(self.config(variant))],
                           capture_output=True, text=True, env=ENV, timeout=TIMEOUT)
        self.assertNotEqual(r.returncode, 0, r.stderr)
        self.assertIn("the ranks do not agree on where the run starts", r.stderr)
        # the checkpoint is untouched: it still resumes to the end
        r = optimize(2, self.config(variant), out, "--resume")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assert_same(variant, out, "resumed after a refused resume")

    def test_an_output_folder_named_like_a_command(self):
        config = self.work / "named.json"
        config.write_text(json.dumps(views.base_config(batch=2, iterations=2, checkpoint_every=2)))
        r = optimize(2, config, self.work / "render")
        self.assertEqual(r.returncode, 0, r.stderr)

    def test_devices_lists_the_ranks_and_render_runs_alone(self):
        r = mpirun(2, "devices")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("MPI: 2 ranks", r.stdout)
        self.assertRegex(r.stdout, r"rank 0 on .* \(local rank 0\): \[\d+\] ")
        self.assertRegex(r.stdout, r"rank 1 on .* \(local rank 1\): \[\d+\] ")
        r = mpirun(2, "render", str(views.GLOBE), "--out", str(self.work / "r.exr"))
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("`tandem render` runs as one process", r.stderr)


def main():
    global TANDEM, MPIEXEC
    if len(sys.argv) < 4:
        raise SystemExit(__doc__.strip().splitlines()[-1])
    TANDEM, views.TANDEM, views.IMGCMP, MPIEXEC = sys.argv[1], sys.argv[1], sys.argv[2], sys.argv[3]
    if not MPIEXEC or MPIEXEC.endswith("NOTFOUND") or not shutil.which(MPIEXEC):
        print("skipped: no MPI launcher (mpirun); scripts/setup-debian.sh installs openmpi-bin")
        sys.exit(77)
    r = subprocess.run([MPIEXEC, "--version"], capture_output=True, text=True)
    if "Open MPI" not in r.stdout + r.stderr:
        print(f"skipped: {MPIEXEC} is not Open MPI's (the test sets Open MPI's options)")
        sys.exit(77)
    unittest.main(argv=[sys.argv[0]], verbosity=2)


if __name__ == "__main__":
    main()
