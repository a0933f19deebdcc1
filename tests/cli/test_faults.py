#!/usr/bin/env python3
"""Faults during `tandem optimize`: nothing written is lost.

    python3 tests/cli/test_faults.py TANDEM_BINARY

- SIGKILL at 2 random moments (scripts/kill-resume.py does 20): `--resume` succeeds and ends
  bit-identical to an uninterrupted run.
- A device allocation that fails (TANDEM_FAIL_ALLOCATION=N, the runtime's hook) while a run
  resumes: one error line, exit 1, the checkpoint untouched and still resumable.
- A full disk (TANDEM_FAIL_WRITE=N: the N-th file write stops half-way with ENOSPC) at every write
  of the first checkpoint interval, the checkpoint's own included: one error line naming the
  file, exit 1, no partial file, the previous checkpoint intact, and the run resumable to the same
  end.
- A damaged checkpoint, or --until before it: one line on stderr, exit 1, nothing rewritten.
- A real write failure from the kernel: a file-size limit (RLIMIT_FSIZE) below the checkpoint's
  size makes its write fail with EFBIG: the same.
Standard library only (unittest); images are compared by their stored words (tandem-imgcmp, built
beside tandem).
"""

import importlib.util
import os
import pathlib
import re
import resource
import signal
import subprocess
import sys
import unittest

ROOT = pathlib.Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("kill_resume", ROOT / "scripts" / "kill-resume.py")
kr = importlib.util.module_from_spec(spec)
spec.loader.exec_module(kr)
TANDEM = None  # set from argv


class Faults(kr.StoppedRun, unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        # The cases below resume a run stopped after its first checkpoint (iteration 3) and
        # carry it to iteration 9 (--until 9): the end they must reach is an uninterrupted
        # run's up to iteration 9.
        cls.set_up_runs(TANDEM, "tandem-faults-", 9)
        cls.expected = kr.outcome(cls.work / "whole")

    def assert_same_end(self, out):
        got = kr.outcome(out)
        for key in self.expected:
            self.assertEqual(got[key], self.expected[key], f"{out.name}: {key}")
        self.assertTrue(kr.same_pixels(self.work / "whole" / "wall.reflectance.exr",
                                       out / "wall.reflectance.exr", kr.imgcmp_beside(TANDEM)))

    def assert_one_line_failure(self, r, what):
        self.assertEqual(r.returncode, 1, f"{what}: {r.stderr}")
        lines = kr.error_lines(r.stderr)
        self.assertEqual(len(lines), 1, f"{what}: {r.stderr}")
        return lines[0]

    def no_temporaries(self, out):
        return [f.name for f in out.iterdir() if kr.TEMPORARY.match(f.name)]

    def test_sigkill_then_resume(self):
        kr.main(["--tandem", TANDEM, "--kills", "2", "--seed", "5",
                 "--work", str(self.work / "kills")])

    def test_failed_device_allocation(self):
        failed = 0
        for n in (1, 3, 6, 12, 24):
            out = self.fresh_copy(f"alloc{n}")
            before = (out / "checkpoint.bin").read_bytes()
            env = dict(os.environ, TANDEM_FAIL_ALLOCATION=str(n))
            r = kr.run(TANDEM, self.config, out, "--resume", "--until", "9", env=env)
            if r.returncode == 0:  # fewer than n allocations: the run went through
                self.assert_same_end(out)
                continue
            failed += 1
            line = self.assert_one_line_failure(r, f"allocation {n}")
            self.assertIn("out of device memory", line)
            self.assertIn("CL_MEM_OBJECT_ALLOCATION_FAILURE (injected", line)
            self.assertEqual((out / "checkpoint.bin").read_bytes(), before)
            r = kr.run(TANDEM, self.config, out, "--resume", "--until", "9")
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assert_same_end(out)
        self.assertGreaterEqual(failed, 4)

    def test_full_disk_at_every_write_of_a_checkpoint_interval(self):
        files = set()
        for n in range(1, 12):
            out = self.fresh_copy(f"write{n}")
            before = (out / "checkpoint.bin").read_bytes()
            env = dict(os.environ, TANDEM_FAIL_WRITE=str(n))
            r = kr.run(TANDEM, self.config, out, "--resume", "--until", "9", env=env)
            line = self.assert_one_line_failure(r, f"write {n}")
            self.assertIn("No space left on device", line)
            # "tandem: error: [iteration N: ]PATH: ...": a write within an iteration names it
            where = re.sub(r"^tandem: error: (iteration \d+: )?", "", line)
            name = pathlib.Path(where.split(": ")[0]).name
            files.add(name)
            self.assertEqual(self.no_temporaries(out), [], line)
            if name == "checkpoint.bin":  # the previous one is intact
                self.assertEqual((out / "checkpoint.bin").read_bytes(), before)
            r = kr.run(TANDEM, self.config, out, "--resume", "--until", "9")
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assert_same_end(out)
        for expected in ("metrics.csv", "checkpoint.bin", "convergence.png"):
            self.assertIn(expected, files)
        self.assertTrue(any(f.startswith("iter_") and f.endswith(".exr") for f in files), files)

    def test_a_damaged_checkpoint_is_one_line_and_left_as_it_is(self):
        out = self.fresh_copy("damaged")
        whole = (out / "checkpoint.bin").read_bytes()
        damaged = whole[: len(whole) // 2]
        (out / "checkpoint.bin").write_bytes(damaged)
        r = kr.run(TANDEM, self.config, out, "--resume", "--until", "9")
        self.assertEqual(r.returncode, 1, r.stderr)
        # the error is all there is on stderr: the run's notes come only once the setup holds
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
        self.assertIn("checkpoint.bin", kr.error_lines(r.stderr)[0])
        self.assertEqual((out / "checkpoint.bin").read_bytes(), damaged)
        # --until before the checkpoint's iteration: one line too, and nothing rewritten
        (out / "checkpoint.bin").write_bytes(whole)
        metrics = (out / "metrics.csv").read_bytes()
        r = kr.run(TANDEM, self.config, out, "--resume", "--until", "2")
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
        self.assertIn("the checkpoint is at iteration 3, past --until 2", r.stderr)
        self.assertEqual((out / "metrics.csv").read_bytes(), metrics)

    def test_file_size_limit_fails_the_checkpoint_write(self):
        out = self.fresh_copy("fsize")
        before = (out / "checkpoint.bin").read_bytes()
        limit = len(before) // 2  # metrics and images fit; the checkpoint does not

        def limited():
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # EFBIG instead of a signal
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

        r = subprocess.run([TANDEM, "optimize", str(self.config), "--out", str(out), "--resume",
                            "--until", "9"],
                           capture_output=True, text=True, preexec_fn=limited)
        line = self.assert_one_line_failure(r, "file size limit")
        self.assertIn("checkpoint.bin: write failed (File too large)", line)
        self.assertEqual(self.no_temporaries(out), [])
        self.assertEqual((out / "checkpoint.bin").read_bytes(), before)
        r = kr.run(TANDEM, self.config, out, "--resume", "--until", "9")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assert_same_end(out)


if __name__ == "__main__":
    TANDEM = sys.argv.pop(1)
    unittest.main(verbosity=2)
