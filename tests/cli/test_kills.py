#!/usr/bin/env python3
"""SIGKILL at chosen places of `tandem optimize`: every --resume ends bit-identical.

    python3 tests/cli/test_kills.py TANDEM_BINARY IMGCMP_BINARY

A run stopped after its first checkpoint (iteration 3 of a CV-PS run on cbox-wall at 16x16, a
checkpoint every 3 iterations) is resumed to iteration 6, and killed on the way with
TANDEM_KILL_AT (runtime/fault.h), once per place:
- half-way through each file write of the interval (the checkpoint's, the re-render's, the
  metrics' appends, the final parameters'...): "write-middle";
- after each write's temporary is complete and flushed, before its rename: "write-complete";
- while the checkpoint write keeps the one it replaces: with its link made ("previous-linked")
  and between the two renames ("previous-kept");
- at the start of each iteration, between checkpoints: "iteration".
Then `--resume` (to iteration 6) must succeed, remove the temporary the kill left (said on stderr),
and end with the outputs of an uninterrupted run: the same files, every image the same stored
words (tandem-imgcmp), metrics.csv the same rows but for its wall-clock "seconds" column,
checkpoint.bin and checkpoint.prev.bin the same but for their wall-clock fields (so the same
parameters, optimizer moments and control-variate state), every other file the same bytes. And temporaries planted as
a killed process leaves them are removed on resume, those of a live process kept.
Standard library only (unittest).
"""

import importlib.util
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import unittest

ROOT = pathlib.Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("kill_resume", ROOT / "scripts" / "kill-resume.py")
kr = importlib.util.module_from_spec(spec)
spec.loader.exec_module(kr)
TANDEM = IMGCMP = None  # set from argv
TEMPORARY = kr.TEMPORARY  # the temporaries' names (core/io/atomic_file.h, temporary_for)


def is_temporary(name):
    return TEMPORARY.match(name) is not None


def run(config, out, *extra, env=None):
    return kr.run(TANDEM, config, out, *extra, env=env)


def metrics_rows(path):
    """metrics.csv's rows without the wall-clock column "seconds"."""
    rows = [line.split(",") for line in path.read_text().splitlines()]
    at = rows[0].index("seconds")
    return [r[:at] + r[at + 1:] for r in rows]


def checkpoint_without_times(path):
    """checkpoint.bin as `tandem checkpoint` describes it once every section's checksum holds: each
    section's size and XXH3 digest, and the run's inputs; without the line naming the file and the
    "clock" section, which holds every wall-clock field (core/inverse/checkpoint.h)."""
    r = subprocess.run([TANDEM, "checkpoint", str(path)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return [line for line in r.stdout.splitlines()[1:] if not line.startswith("  section clock ")]


def differences(expected, got):
    """What differs between two output folders (see the top of this file); empty when nothing."""
    names_e = sorted(f.name for f in expected.iterdir())
    names_g = sorted(f.name for f in got.iterdir())
    if names_e != names_g:
        return [f"files: {names_e} against {names_g}"]
    found = []
    images = [str(d / name) for name in names_e if name.endswith(".exr") for d in (expected, got)]
    r = subprocess.run([IMGCMP, *images], capture_output=True, text=True)
    if r.returncode != 0:
        found += (r.stdout + r.stderr).strip().splitlines()
    for name in names_e:
        a, b = expected / name, got / name
        if name.endswith(".exr"):
            continue
        if name == "metrics.csv":
            if metrics_rows(a) != metrics_rows(b):
                found.append(f"{name}: {metrics_rows(a)} against {metrics_rows(b)}")
        elif name in ("checkpoint.bin", "checkpoint.prev.bin"):
            if checkpoint_without_times(a) != checkpoint_without_times(b):
                found.append(f"{name}: differs (wall-clock times aside)")
        elif a.read_bytes() != b.read_bytes():
            found.append(f"{name}: differs")
    return found


class Kills(kr.StoppedRun, unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.set_up_runs(TANDEM, "tandem-kills-", 6, res=16, spp=1, target_spp=4)

    def temporaries(self, out):
        return sorted(f.name for f in out.iterdir() if is_temporary(f.name))

    def kill_and_resume(self, where, n):
        """Resumes `part` to iteration 6 with a kill at the n-th passage of `where`, then resumes
        it again without. Returns None when the run has fewer passages (it finished), else the
        temporaries the kill left and the output folder."""
        out = self.fresh_copy(f"{where}-{n}")
        env = dict(os.environ, TANDEM_KILL_AT=f"{where}:{n}")
        r = run(self.config, out, "--resume", "--until", "6", env=env)
        if r.returncode == 0:
            return None
        self.assertEqual(r.returncode, -signal.SIGKILL, f"{where}:{n}: {r.stderr}")
        left = self.temporaries(out)
        r = run(self.config, out, "--resume", "--until", "6")
        self.assertEqual(r.returncode, 0, f"{where}:{n}: {r.stderr}")
        if left:
            self.assertIn(f"removed {len(left)} unfinished file(s)", r.stderr, f"{where}:{n}")
        self.assertEqual(self.temporaries(out), [], f"{where}:{n}")
        self.assertEqual(differences(self.work / "whole", out), [], f"{where}:{n}")
        return left, out

    def target(self, temporary):
        """The file a temporary was for: .NAME.tmpPID[.ext] -> NAME[.ext]."""
        m = TEMPORARY.match(temporary)
        return m.group(1) + (m.group(2) or "")

    def test_kill_before_each_rename(self):
        written = []
        for n in range(1, 40):
            result = self.kill_and_resume("write-complete", n)
            if result is None:
                break
            left, _ = result
            self.assertEqual(len(left), 1, f"write-complete:{n}: {left}")
            written.append(self.target(left[0]))
        print(f"\n  {len(written)} kills before a rename, of: {', '.join(written)}",
              file=sys.stderr)
        # every kind of file the interval writes, the checkpoint among them, was killed in
        for name in ("metrics.csv", "target.exr", "iter_0006.exr", "alpha_0006.exr",
                     "variance_0006.exr", "checkpoint.bin", "convergence.png",
                     "wall.reflectance.exr", "wall.reflectance.png", "params.json"):
            self.assertIn(name, written)

    def test_kill_half_way_through_each_write(self):
        partial_record = partial_checkpoint = False
        for n in range(1, 40):
            out = self.fresh_copy(f"peek-{n}")
            env = dict(os.environ, TANDEM_KILL_AT=f"write-middle:{n}")
            r = run(self.config, out, "--resume", "--until", "6", env=env)
            if r.returncode == 0:
                break
            self.assertEqual(r.returncode, -signal.SIGKILL, r.stderr)
            # what the kill left: a half-written temporary, or a half-appended record
            left = self.temporaries(out)
            metrics = (out / "metrics.csv").read_text()
            partial_record |= not left and not metrics.endswith("\n")
            partial_checkpoint |= any(self.target(t) == "checkpoint.bin" and
                                      0 < (out / t).stat().st_size <
                                      (self.work / "whole" / "checkpoint.bin").stat().st_size
                                      for t in left)
            r = run(self.config, out, "--resume", "--until", "6")
            self.assertEqual(r.returncode, 0, f"write-middle:{n}: {r.stderr}")
            self.assertEqual(self.temporaries(out), [], f"write-middle:{n}")
            self.assertEqual(differences(self.work / "whole", out), [], f"write-middle:{n}")
            shutil.rmtree(out)
        print(f"\n  {n - 1} kills half-way through a write", file=sys.stderr)
        self.assertGreaterEqual(n - 1, 13)  # the resumed interval's writes and appends
        self.assertTrue(partial_record, "no kill landed inside a metrics record")
        self.assertTrue(partial_checkpoint, "no kill landed inside the checkpoint's write")

    def test_kill_while_the_previous_checkpoint_is_kept(self):
        # The checkpoint write at iteration 6 keeps the one of iteration 3 as checkpoint.prev.bin
        # (core/io/atomic_file.h): a kill with its link made leaves both temporaries (the new
        # checkpoint's and the link); one between the two renames leaves the new checkpoint's,
        # and the two names links to the checkpoint of iteration 3, which the next write must
        # recognise (a rename of a link over another of the same file does nothing).
        for where, left_for in (("previous-linked", ["checkpoint.bin", "checkpoint.prev.bin"]),
                                ("previous-kept", ["checkpoint.bin"])):
            out = self.fresh_copy(f"{where}-killed")
            env = dict(os.environ, TANDEM_KILL_AT=f"{where}:1")
            r = run(self.config, out, "--resume", "--until", "6", env=env)
            self.assertEqual(r.returncode, -signal.SIGKILL, f"{where}: {r.stderr}")
            self.assertEqual([self.target(t) for t in self.temporaries(out)], left_for, where)
            if where == "previous-kept":
                self.assertTrue(os.path.samefile(out / "checkpoint.bin",
                                                 out / "checkpoint.prev.bin"))
            r = run(self.config, out, "--resume", "--until", "6")
            self.assertEqual(r.returncode, 0, f"{where}: {r.stderr}")
            self.assertEqual(self.temporaries(out), [], where)
            self.assertEqual(differences(self.work / "whole", out), [], where)
            self.assertIsNone(self.kill_and_resume(where, 2))  # one such write in the interval

    def test_kill_between_checkpoints(self):
        for n in (1, 2, 3):  # at the start of iterations 4, 5 and 6
            left, out = self.kill_and_resume("iteration", n)
            self.assertEqual(left, [])
        self.assertIsNone(self.kill_and_resume("iteration", 4))  # no iteration 7 before --until

    def test_planted_stale_temporaries_are_removed_on_resume(self):
        out = self.fresh_copy("planted")
        gone = subprocess.Popen(["true"])
        gone.wait()  # its process id is free now
        stale = [f".checkpoint.bin.tmp{gone.pid}", f".iter_0006.tmp{gone.pid}.exr"]
        live = f".params.json.tmp{os.getpid()}"  # this test's own process: alive
        for name in stale + [live]:
            (out / name).write_bytes(b"unfinished")
        r = run(self.config, out, "--resume", "--until", "6")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("removed 2 unfinished file(s)", r.stderr)
        self.assertEqual(self.temporaries(out), [live])
        self.assertEqual((out / live).read_bytes(), b"unfinished")
        (out / live).unlink()
        self.assertEqual(differences(self.work / "whole", out), [])


if __name__ == "__main__":
    TANDEM = sys.argv.pop(1)
    IMGCMP = sys.argv.pop(1)
    unittest.main(verbosity=2)
