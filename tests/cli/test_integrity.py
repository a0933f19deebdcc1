#!/usr/bin/env python3
"""The integrity of `tandem optimize`'s output folder (core/inverse/checkpoint.h, core/io/sections.h,
core/io/folder_lock.h):

- Every section of a checkpoint damaged in turn, three ways (a flipped bit, a truncation inside
  it, a zeroed block): `tandem checkpoint` refuses it in one line naming the section, and
  `--resume` falls back to the previous checkpoint with a notice naming it, and ends bit-identical
  to an uninterrupted run. Both checkpoints damaged: one line, exit 1.
- Two optimizes into one folder: the second exits 1 at once naming the folder and the first's
  process, having touched nothing; the first ends bit-identical to a lone run. A SIGKILLed holder
  leaves no lock behind.
- Each kind of input changed between two halves of a run (the scene file, a mesh, a texture, the
  target image, the config): `--resume` refused in one line naming the file, nothing touched;
  `--resume --force` continues, says so, and marks the rows after it in metrics.csv and the
  summary.

The checkpoint's layout is read here from its definition in core/io/sections.h (magic; then per
section: name length u32, name, payload length u64, payload, XXH3-64 u64), independently of the
reader under test.

    python3 tests/cli/test_integrity.py TANDEM_BINARY
"""

import hashlib
import importlib.util
import json
import os
import pathlib
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
import unittest

ROOT = pathlib.Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("kill_resume", ROOT / "scripts" / "kill-resume.py")
kr = importlib.util.module_from_spec(spec)
spec.loader.exec_module(kr)
TANDEM = None  # set from argv


def sections(data):
    """[(name, start, payload start, payload end, end)] of a checkpoint's bytes."""
    assert data[:7] == b"TNDMCKP", "not a checkpoint"
    out, at = [], 8
    while at < len(data):
        start = at
        (n,) = struct.unpack_from("<I", data, at)
        name = data[at + 4:at + 4 + n].decode()
        (size,) = struct.unpack_from("<Q", data, at + 4 + n)
        payload = at + 4 + n + 8
        at = payload + size + 8
        out.append((name, start, payload, payload + size, at))
    assert at == len(data)
    return out


def damaged(data, section, how):
    """`data` with `section` (a sections() entry) damaged `how`: "flip" (one bit in the middle of
    its payload, or of its name when the payload is shorter than 8 bytes), "truncate" (cut in the
    middle of its payload) or "zero" (16 bytes zeroed from its payload's start, its length field's
    when the payload is shorter)."""
    name, start, p0, p1, end = section
    d = bytearray(data)
    if how == "flip":
        at = (p0 + p1) // 2 if p1 - p0 >= 8 else start + 5
        d[at] ^= 0x40
        return bytes(d)
    if how == "truncate":
        return bytes(d[:(p0 + p1) // 2 if p1 > p0 else p0 - 4])
    at = p0 if p1 - p0 >= 16 else p0 - 8
    block = bytes(16)
    assert d[at:at + 16] != block
    d[at:at + 16] = block
    return bytes(d)


def label(name):
    """How the reader names a section: the index by itself, the others quoted."""
    return "its index" if name == "index" else f"('{name}')"


def snapshot(folder, lock_time=False):
    """Every file of a folder with a digest of its bytes and its modification time; the lock
    file's time only with `lock_time` (a run that takes the lock and then stops with an error
    writes its id there). Digests, not bytes: a failing comparison prints a short diff."""
    return {f.name: (hashlib.sha256(f.read_bytes()).hexdigest(),
                     f.stat().st_mtime_ns if lock_time or f.name != ".tandem.lock" else 0)
            for f in sorted(folder.iterdir())}


def wait_for_lock(out, pid, proc):
    """Waits until process `pid` holds the folder's lock (its id in the lock file)."""
    lock = out / ".tandem.lock"
    for _ in range(6000):
        if lock.exists() and lock.read_text().strip() == str(pid):
            return
        if proc.poll() is not None:
            raise AssertionError(f"the first run ended before it was seen holding {lock}")
        time.sleep(0.01)
    raise AssertionError(f"{lock}: process {pid} never held it")


BOX_OBJ = """# a unit cube, [-1, 1]^3
v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1
f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 4 7 3\nf 4 8 7\nf 1 5 8\nf 1 8 4
f 2 3 7\nf 2 7 6
"""


class Integrity(kr.StoppedRun, unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        # "whole": an uninterrupted run to iteration 9; "part" stopped at 3. Checkpoints every 3.
        cls.set_up_runs(TANDEM, "tandem-integrity-", 9, res=16, spp=1, target_spp=4)
        cls.expected = kr.outcome(cls.work / "whole")
        # "two": stopped at 6, so that it holds two checkpoints (6, and 3 as the previous one)
        r = kr.run(TANDEM, cls.config, cls.work / "two", "--until", "6")
        assert r.returncode == 0, r.stderr
        # the inputs of the changed-input cases: a scene with a mesh and a texture of its own,
        # and a target image rendered from it
        inputs = cls.work / "inputs"
        (inputs / "textures").mkdir(parents=True)
        shutil.copy(ROOT / "scenes" / "textures" / "wall.png", inputs / "textures" / "wall.png")
        (inputs / "box.obj").write_text(BOX_OBJ)
        scene = (ROOT / "scenes" / "cbox-wall.xml").read_text()
        short = scene.index('<shape type="cube" id="short-box">')
        scene = (scene[:short] + '<shape type="obj" id="short-box">\n'
                 '        <string name="filename" value="box.obj"/>' +
                 scene[short + len('<shape type="cube" id="short-box">'):])
        (inputs / "scene.xml").write_text(scene)
        r = subprocess.run([TANDEM, "render", str(inputs / "scene.xml"), "-D", "res=16", "--spp",
                            "4", "--out", str(inputs / "target.exr")], capture_output=True,
                           text=True)
        assert r.returncode == 0, r.stderr
        config = {"scene": "scene.xml", "defines": {"res": 16}, "target": {"image": "target.exr"},
                  "params": {"wall.reflectance": {"lr": 0.02, "init": 0.5}}, "iterations": 60,
                  "spp": 1, "spp_grad": 1, "loss": "l2", "seed": 7, "cv": "ps",
                  "checkpoint_every": 3, "image_error_spp": 1}
        (inputs / "config.json").write_text(json.dumps(config))

    def assert_same_end(self, out, what):
        got = kr.outcome(out)
        for key in self.expected:
            self.assertEqual(got[key], self.expected[key], f"{what}: {key}")
        self.assertTrue(kr.same_pixels(self.work / "whole" / "wall.reflectance.exr",
                                       out / "wall.reflectance.exr", kr.imgcmp_beside(TANDEM)),
                        what)

    def copy_of(self, source, name):
        out = self.work / name
        shutil.rmtree(out, ignore_errors=True)
        shutil.copytree(self.work / source, out)
        return out

    def test_each_damaged_section_is_named_and_the_previous_checkpoint_resumes(self):
        data = (self.work / "two" / "checkpoint.bin").read_bytes()
        parts = sections(data)
        names = [s[0] for s in parts]
        # every section the format promises is there
        for expected in ("index", "run", "inputs", "metrics", "clock", "state", "state:theta",
                         "state:theta_prev", "state:adam.m", "state:adam.v", "state:cv.state"):
            self.assertIn(expected, names)
        for section in parts:
            for how in ("flip", "truncate", "zero"):
                what = f"{section[0]}, {how}"
                out = self.copy_of("two", f"damaged-{section[0].replace(':', '-')}-{how}")
                bad = damaged(data, section, how)
                (out / "checkpoint.bin").write_bytes(bad)
                r = subprocess.run([TANDEM, "checkpoint", str(out / "checkpoint.bin")],
                                   capture_output=True, text=True)
                self.assertEqual(r.returncode, 1, what)
                line = kr.error_lines(r.stderr)
                self.assertEqual(len(line), 1, f"{what}: {r.stderr}")
                self.assertIn(label(section[0]), line[0], what)
                r = kr.run(TANDEM, self.config, out, "--resume", "--until", "9")
                self.assertEqual(r.returncode, 0, f"{what}: {r.stderr}")
                notice = [l for l in r.stderr.splitlines() if "resuming from" in l]
                self.assertEqual(len(notice), 1, f"{what}: {r.stderr}")
                self.assertIn(label(section[0]), notice[0], what)
                self.assertIn("checkpoint.prev.bin (iteration 3)", notice[0], what)
                self.assertEqual((out / "checkpoint.bin.damaged").read_bytes(), bad, what)
                self.assert_same_end(out, what)

    def test_a_damaged_format_byte_is_damage_not_another_version(self):
        # the magic is outside every checksum: its format byte '5' with one bit flipped is '4'
        data = bytearray((self.work / "two" / "checkpoint.bin").read_bytes())
        self.assertEqual(data[:8], b"TNDMCKP5")
        data[7] ^= 0x01
        out = self.copy_of("two", "damaged-format")
        (out / "checkpoint.bin").write_bytes(bytes(data))
        r = subprocess.run([TANDEM, "checkpoint", str(out / "checkpoint.bin")],
                           capture_output=True, text=True)
        self.assertEqual(kr.error_lines(r.stderr), [
            f"tandem: error: {out / 'checkpoint.bin'}: its format byte is damaged (the sections "
            "after it are whole)"])
        r = kr.run(TANDEM, self.config, out, "--resume", "--until", "9")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("checkpoint.prev.bin (iteration 3)", r.stderr)
        self.assert_same_end(out, "a damaged format byte")
        # a real older checkpoint (format 4: another layout) is another version, said as such
        (out / "old.bin").write_bytes(b"TNDMCKP4" + bytes(64))
        r = subprocess.run([TANDEM, "checkpoint", str(out / "old.bin")], capture_output=True,
                           text=True)
        self.assertIn("a checkpoint of another Tandem version (format 4, this one reads 5)",
                      r.stderr)

    def test_a_refused_fallback_touches_nothing(self):
        # the newest checkpoint (6) damaged, and --until 2 before the previous one (3): refused,
        # and neither the damaged checkpoint set aside nor a dead run's temporary removed, as
        # both are only once every check has passed
        out = self.copy_of("two", "refused-fallback")
        data = (out / "checkpoint.bin").read_bytes()
        (out / "checkpoint.bin").write_bytes(damaged(data, sections(data)[-1], "flip"))
        gone = subprocess.Popen(["true"])
        gone.wait()  # its process id is free now
        (out / f".checkpoint.bin.tmp{gone.pid}").write_bytes(b"left by a killed run")
        before = snapshot(out)
        r = kr.run(TANDEM, self.config, out, "--resume", "--until", "2")
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertEqual(r.stderr.strip().splitlines(), [
            f"tandem: error: {out / 'checkpoint.prev.bin'}: the checkpoint is at iteration 3, "
            "past --until 2"])
        self.assertEqual(snapshot(out), before)

    def test_a_damaged_newest_and_a_previous_of_other_inputs_are_both_said(self):
        out = self.copy_of("two", "damaged-and-changed")
        data = (out / "checkpoint.bin").read_bytes()
        (out / "checkpoint.bin").write_bytes(damaged(data, sections(data)[-1], "flip"))
        config = json.loads(self.config.read_text())
        config["seed"] = 8
        other = self.work / "other-seed.json"
        other.write_text(json.dumps(config))
        before = snapshot(out)
        r = kr.run(TANDEM, other, out, "--resume", "--until", "9")
        self.assertEqual(r.returncode, 1, r.stderr)
        lines = r.stderr.strip().splitlines()
        self.assertEqual(len(lines), 1, r.stderr)
        self.assertIn(f"{out / 'checkpoint.bin'}: section ", lines[0])
        self.assertIn(f"; and the previous one: {other}: seed changed since the checkpoint (7 -> 8)",
                      lines[0])
        self.assertEqual(snapshot(out), before)

    def test_both_checkpoints_damaged_is_one_line_and_nothing_rewritten(self):
        out = self.copy_of("two", "damaged-both")
        for name in ("checkpoint.bin", "checkpoint.prev.bin"):
            data = (out / name).read_bytes()
            (out / name).write_bytes(damaged(data, sections(data)[-1], "flip"))
        before = snapshot(out)
        r = kr.run(TANDEM, self.config, out, "--resume", "--until", "9")
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
        self.assertIn("checkpoint.bin: section", r.stderr)
        self.assertIn("and the previous one: ", r.stderr)
        self.assertEqual(snapshot(out), before)

    def test_a_second_writer_is_refused_and_the_first_finishes_as_a_lone_run(self):
        out = self.work / "locked"
        first = subprocess.Popen([TANDEM, "optimize", str(self.config), "--out", str(out),
                                  "--until", "9"], stdout=subprocess.DEVNULL,
                                 stderr=subprocess.PIPE, text=True)
        try:
            wait_for_lock(out, first.pid, first)
            os.kill(first.pid, signal.SIGSTOP)  # the folder holds still while the second tries
            before = snapshot(out, lock_time=True)
            t0 = time.monotonic()
            r = kr.run(TANDEM, self.config, out, "--until", "9")
            seconds = time.monotonic() - t0
            after = snapshot(out, lock_time=True)
        finally:
            os.kill(first.pid, signal.SIGCONT)
        _, stderr = first.communicate(timeout=600)
        self.assertEqual(first.returncode, 0, stderr)
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertEqual(r.stderr.strip().splitlines(), [
            f"tandem: error: {out}: in use by another tandem optimize (process {first.pid} holds "
            ".tandem.lock); wait for it to finish or write elsewhere (--out)"])
        self.assertLess(seconds, 30.0)  # at once: before any device work (a run takes longer)
        self.assertEqual(after, before)
        self.assert_same_end(out, "the first writer")
        self.assertEqual((out / ".tandem.lock").read_bytes(), b"")

    def test_a_killed_holder_leaves_no_lock(self):
        out = self.work / "killed-holder"
        holder = subprocess.Popen([TANDEM, "optimize", str(self.config), "--out", str(out),
                                   "--until", "9"], stdout=subprocess.DEVNULL,
                                  stderr=subprocess.DEVNULL)
        wait_for_lock(out, holder.pid, holder)
        holder.kill()
        holder.wait()
        r = kr.run(TANDEM, self.config, out, "--resume", "--until", "9")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assert_same_end(out, "after a killed holder")

    def test_each_changed_input_is_named_and_force_continues(self):
        def scene(d):
            p = d / "scene.xml"
            p.write_text(p.read_text().replace("0.570068, 0.0430135, 0.0443706", "0.1, 0.6, 0.1"))
            return p

        def mesh(d):
            p = d / "box.obj"
            p.write_text(p.read_text().replace("v 1 1 1", "v 1 1.25 1"))
            return p

        def texture(d):
            p = d / "textures" / "wall.png"
            shutil.copy(ROOT / "scenes" / "textures" / "floor.png", p)  # the same size
            return p

        def target(d):
            p = d / "target.exr"
            r = subprocess.run([TANDEM, "render", str(d / "scene.xml"), "-D", "res=16", "--spp",
                                "8", "--out", str(p)], capture_output=True, text=True)
            self.assertEqual(r.returncode, 0, r.stderr)
            return p

        def config(d):
            p = d / "config.json"
            c = json.loads(p.read_text())
            c["params"]["wall.reflectance"]["lr"] = 0.03
            p.write_text(json.dumps(c))
            return p

        for change in (scene, mesh, texture, target, config):
            what = change.__name__
            d = self.work / f"changed-{what}"
            shutil.rmtree(d, ignore_errors=True)
            shutil.copytree(self.work / "inputs", d)
            out = d / "out"
            r = kr.run(TANDEM, d / "config.json", out, "--until", "3")
            self.assertEqual(r.returncode, 0, f"{what}: {r.stderr}")
            changed = change(d)
            before = snapshot(out)
            r = kr.run(TANDEM, d / "config.json", out, "--resume", "--until", "6")
            self.assertEqual(r.returncode, 1, f"{what}: {r.stderr}")
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, f"{what}: {r.stderr}")
            self.assertTrue(r.stderr.startswith(f"tandem: error: {changed}: "), f"{what}: {r.stderr}")
            self.assertIn("changed since the checkpoint", r.stderr, what)
            self.assertEqual(snapshot(out), before, what)
            r = kr.run(TANDEM, d / "config.json", out, "--resume", "--force", "--until", "6",
                       "--json")
            self.assertEqual(r.returncode, 0, f"{what}: {r.stderr}")
            self.assertIn(f"tandem optimize: --force: {changed}: ", r.stderr, what)
            self.assertTrue(json.loads(r.stdout)["inputs_changed"], what)
            with open(out / "metrics.csv") as f:
                rows = [line.rstrip("\n").split(",") for line in f]
            self.assertEqual(rows[0][-1], "inputs_changed")
            self.assertEqual([row[-1] for row in rows[1:]], ["", "", "", "1", "1", "1"], what)
            # the next resume is of the changed inputs, and goes on marking the rows
            r = kr.run(TANDEM, d / "config.json", out, "--resume", "--until", "9")
            self.assertEqual(r.returncode, 0, f"{what}: {r.stderr}")
            with open(out / "metrics.csv") as f:
                self.assertEqual([line.rstrip("\n").split(",")[-1] for line in f][-3:],
                                 ["1", "1", "1"], what)

    def test_unchanged_inputs_in_another_place_resume(self):
        # the checkpoint records content, not paths: the inputs moved elsewhere resume
        d = self.work / "moved-a"
        shutil.rmtree(d, ignore_errors=True)
        shutil.copytree(self.work / "inputs", d)
        r = kr.run(TANDEM, d / "config.json", d / "out", "--until", "3")
        self.assertEqual(r.returncode, 0, r.stderr)
        moved = self.work / "moved-b"
        shutil.rmtree(moved, ignore_errors=True)
        d.rename(moved)
        r = kr.run(TANDEM, moved / "config.json", moved / "out", "--resume", "--until", "6")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertNotIn("--force", r.stderr)


if __name__ == "__main__":
    TANDEM = sys.argv.pop(1)
    unittest.main()
