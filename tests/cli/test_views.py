#!/usr/bin/env python3
"""Several views (scenes/globe.xml: eight sensors, at 16x16) through `tandem optimize` and
`tandem render`:

- Kill-resume: a run over "views": "all" in batches of 3 (so batches straddle the shuffled
  epochs), CV-PS, and the same with ReSTIR on the adjoint; 12 iterations, a checkpoint every 4.
  SIGKILLed (TANDEM_KILL_AT, runtime/fault.h) at the start of iteration 6 (between checkpoints),
  half-way through the checkpoint write of iteration 8, and while that write keeps the previous
  checkpoint; `--resume` to the end gives the uninterrupted run's outputs: every image of views/*/
  the same stored words (tandem-imgcmp), params.json and the other files the same bytes,
  metrics.csv the same but for its wall-clock column, the checkpoints the same but for their
  wall-clock section (so each view's control-variate state, reservoirs and last parameters).
- `--until 6` then `--resume`: the same end, but for what a stop off the checkpoint grid adds
  (docs/cli.md: "as an interruption would"): the re-render of iteration 6 (views/K/*_0006.exr,
  and its image_error in metrics.csv, in the checkpoints' "metrics" section and in the plot
  convergence.png).
- Photograph targets: every sensor rendered by `tandem render --sensor all` as EXR and PNG;
  with the EXRs as "target": {"images": [...]}, each views/K/target.exr stores the input's words;
  with the PNGs, it agrees with the EXR within half an 8-bit sRGB code step, pixel by pixel.
- Bad target inputs, each one line "tandem: error: ..." naming the file, exit 1: 7 images for 8
  sensors, an image of another size, a missing file, a NaN texel, masks of the wrong count,
  "batch" over the views; and `tandem render --sensor nope` names the sensors there are.

Standard library only (unittest; EXR files are read and written here with zlib and struct).

    python3 tests/cli/test_views.py TANDEM_BINARY IMGCMP_BINARY
"""

import importlib.util
import json
import math
import os
import pathlib
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import unittest
import zlib

ROOT = pathlib.Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("kill_resume", ROOT / "scripts" / "kill-resume.py")
kr = importlib.util.module_from_spec(spec)
spec.loader.exec_module(kr)
TANDEM = IMGCMP = None  # set from argv
GLOBE = ROOT / "scenes" / "globe.xml"
VIEWS = 8


def run(config, out, *extra, env=None):
    return kr.run(TANDEM, config, out, *extra, env=env)


def base_config(**extra):
    """A run on the globe at 16x16 recovering its texture from a rendered target."""
    config = {"scene": str(GLOBE), "defines": {"res": 16},
              "target": {"scene": str(GLOBE), "defines": {"res": 16}, "spp": 8},
              "params": {"globe.reflectance": {"lr": 0.02, "init": 0.5}},
              "iterations": 12, "spp": 1, "spp_grad": 1, "loss": "l2", "seed": 7, "cv": "ps",
              "checkpoint_every": 4, "image_error_spp": 1, "views": "all", "batch": 3}
    config.update(extra)
    return config


# --- EXR, as Tandem writes it (OpenImageIO: scanlines, float channels, ZIP) --------------------

def read_exr(path):
    """(width, height, {channel: [floats row-major from the top left]}) of a single-part scanline
    EXR, uncompressed or ZIP(S), float or half channels."""
    data = pathlib.Path(path).read_bytes()
    assert data[:4] == b"\x76\x2f\x31\x01", f"{path}: not EXR"
    at, header = 8, {}
    while data[at] != 0:
        name, at = data[at:data.index(0, at)].decode(), data.index(0, at) + 1
        kind, at = data[at:data.index(0, at)].decode(), data.index(0, at) + 1
        (size,) = struct.unpack_from("<i", data, at)
        header[name] = (kind, data[at + 4:at + 4 + size])
        at += 4 + size
    at += 1
    channels, raw = [], header["channels"][1]
    while raw[0] != 0:
        name, raw = raw[:raw.index(0)].decode(), raw[raw.index(0) + 1:]
        channels.append((name, struct.unpack_from("<i", raw)[0]))
        raw = raw[16:]
    x0, y0, x1, y1 = struct.unpack("<4i", header["dataWindow"][1])
    width, height = x1 - x0 + 1, y1 - y0 + 1
    compression = header["compression"][1][0]
    lines = {0: 1, 2: 1, 3: 16}[compression]
    chunks = (height + lines - 1) // lines
    offsets = struct.unpack_from(f"<{chunks}Q", data, at)
    pixels = {name: [] for name, _ in channels}
    for offset in offsets:
        y, size = struct.unpack_from("<ii", data, offset)
        block = data[offset + 8:offset + 8 + size]
        rows = min(lines, y1 + 1 - y)
        expected = rows * width * sum(2 if t == 1 else 4 for _, t in channels)
        if compression and size < expected:  # ZIP: inflate, undo the predictor and interleave
            t = bytearray(zlib.decompress(block))
            for i in range(1, len(t)):
                t[i] = (t[i - 1] + t[i] - 128) & 0xFF
            half = (len(t) + 1) // 2
            block = bytearray(len(t))
            block[0::2], block[1::2] = t[:half], t[half:]
        at = 0
        for _ in range(rows):
            for name, kind in channels:
                fmt, step = ("e", 2) if kind == 1 else ("f", 4)
                pixels[name] += struct.unpack_from(f"<{width}{fmt}", block, at)
                at += width * step
    return width, height, pixels


def write_exr(path, width, height, pixels):
    """An uncompressed scanline EXR of float channels `pixels` ({name: floats}, as read_exr)."""
    def attribute(name, kind, value):
        return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value
    names = sorted(pixels)
    chlist = b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for n in names)
    window = struct.pack("<4i", 0, 0, width - 1, height - 1)
    header = (b"\x76\x2f\x31\x01" + struct.pack("<i", 2) +
              attribute("channels", "chlist", chlist + b"\0") +
              attribute("compression", "compression", b"\0") +
              attribute("dataWindow", "box2i", window) +
              attribute("displayWindow", "box2i", window) +
              attribute("lineOrder", "lineOrder", b"\0") +
              attribute("pixelAspectRatio", "float", struct.pack("<f", 1.0)) +
              attribute("screenWindowCenter", "v2f", struct.pack("<2f", 0.0, 0.0)) +
              attribute("screenWindowWidth", "float", struct.pack("<f", 1.0)) + b"\0")
    line = 8 + 4 * width * len(names)
    table = b"".join(struct.pack("<Q", len(header) + 8 * height + y * line) for y in range(height))
    rows = b"".join(struct.pack("<ii", y, line - 8) +
                    b"".join(struct.pack(f"<{width}f", *pixels[n][y * width:(y + 1) * width])
                             for n in names) for y in range(height))
    pathlib.Path(path).write_bytes(header + table + rows)


def srgb_encode(x):
    x = min(max(x, 0.0), 1.0)
    return 12.92 * x if x <= 0.0031308 else 1.055 * x ** (1 / 2.4) - 0.055


def srgb_decode(v):
    return v / 12.92 if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4


# --- output folders ------------------------------------------------------------------------------

def files_of(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())


def metrics_rows(path):
    """metrics.csv's rows without the wall-clock column "seconds"."""
    rows = [line.split(",") for line in path.read_text().splitlines()]
    at = rows[0].index("seconds")
    return [r[:at] + r[at + 1:] for r in rows]


def checkpoint_sections(path, skip=()):
    """A checkpoint's magic and sections [(name, bytes)], by its layout in core/io/sections.h
    (magic; per section: name length u32, name, payload length u64, payload, XXH3-64 u64), without
    the sections named in `skip`."""
    data = path.read_bytes()
    found, at = [("magic", data[:8])], 8
    while at < len(data):
        (n,) = struct.unpack_from("<I", data, at)
        name = data[at + 4:at + 4 + n].decode()
        (size,) = struct.unpack_from("<Q", data, at + 4 + n)
        end = at + 4 + n + 8 + size + 8
        if name not in skip:
            found.append((name, data[at:end]))
        at = end
    return found


def differences(expected, got, stopped_at=None):
    """What differs between two output folders, views/*/ included; empty when nothing. With
    `stopped_at`, `got` was stopped there off the checkpoint grid and resumed: it has that
    iteration's re-renders more, and its image_error."""
    names = files_of(expected)
    extra = []
    if stopped_at is not None:
        extra = [f"views/{k}/{kind}_{stopped_at:04d}.exr" for k in range(VIEWS)
                 for kind in ("alpha", "iter", "variance")]
    if sorted(names + extra) != files_of(got):
        return [f"files: {names} (and {extra}) against {files_of(got)}"]
    found = []
    images = [str(d / n) for n in names if n.endswith(".exr") for d in (expected, got)]
    r = subprocess.run([IMGCMP, *images], capture_output=True, text=True)
    if r.returncode != 0:
        found += (r.stdout + r.stderr).strip().splitlines()
    skip = ["clock"] if stopped_at is None else ["clock", "metrics"]
    for name in names:
        a, b = expected / name, got / name
        if name.endswith(".exr"):
            continue
        if name == "metrics.csv":
            want, have = metrics_rows(a), metrics_rows(b)
            if stopped_at is not None:  # the stop's re-render filled image_error
                column = want[0].index("image_error")
                row = [r[0] for r in have].index(str(stopped_at))
                if want[row][column] != "" or have[row][column] == "":
                    found.append(f"{name}: the image_error of iteration {stopped_at}: "
                                 f"{want[row][column]!r} against {have[row][column]!r}")
                have[row][column] = ""
            if want != have:
                found.append(f"{name}: {want} against {have}")
        elif name in ("checkpoint.bin", "checkpoint.prev.bin"):
            if checkpoint_sections(a, skip) != checkpoint_sections(b, skip):
                found.append(f"{name}: differs (sections {skip} aside)")
        elif name == "convergence.png" and stopped_at is not None:
            continue  # it plots the metrics, the stop's image_error among them
        elif a.read_bytes() != b.read_bytes():
            found.append(f"{name}: differs")
    return found


def temporaries(out):
    return sorted(str(p.relative_to(out)) for p in out.rglob("*") if kr.TEMPORARY.match(p.name))


def target_of(temporary):
    """The file a temporary (a path) was for: .NAME.tmpPID[.ext] -> NAME[.ext]."""
    m = kr.TEMPORARY.match(pathlib.PurePath(temporary).name)
    return str(pathlib.PurePath(temporary).with_name(m.group(1) + (m.group(2) or "")))


class KillResume(unittest.TestCase):
    """Per variant (CV-PS; CV-PS with ReSTIR on the adjoint): "whole", an uninterrupted run, and
    "part", stopped at its first checkpoint (iteration 4)."""

    VARIANTS = {"cv": base_config(), "restir": base_config(restir={"adjoint": True})}

    @classmethod
    def setUpClass(cls):
        cls.work = pathlib.Path(tempfile.mkdtemp(prefix="tandem-views-"))
        cls.addClassCleanup(shutil.rmtree, cls.work, ignore_errors=True)  # setUpClass failing too
        cls.stderr = {}
        for variant, config in cls.VARIANTS.items():
            path = cls.work / f"{variant}.json"
            path.write_text(json.dumps(config))
            r = run(path, cls.work / variant / "whole")
            assert r.returncode == 0, r.stderr
            cls.stderr[variant] = r.stderr
            r = run(path, cls.work / variant / "part", "--until", "4")
            assert r.returncode == 0, r.stderr

    def config(self, variant):
        return self.work / f"{variant}.json"

    def copy(self, variant, source, name):
        out = self.work / variant / name
        shutil.rmtree(out, ignore_errors=True)
        if source:
            shutil.copytree(self.work / variant / source, out)
        return out

    def killed(self, variant, out, where, *extra):
        """Runs `--resume` (or a fresh run with no --resume in `extra`) into `out` with a kill at
        `where`; returns the run."""
        env = dict(os.environ, TANDEM_KILL_AT=where)
        return run(self.config(variant), out, *extra, env=env)

    def assert_resumes_to_the_end(self, variant, out, what):
        left = temporaries(out)
        r = run(self.config(variant), out, "--resume")
        self.assertEqual(r.returncode, 0, f"{what}: {r.stderr}")
        if left:
            self.assertIn(f"removed {len(left)} unfinished file(s)", r.stderr, what)
        self.assertEqual(temporaries(out), [], what)
        self.assertEqual(differences(self.work / variant / "whole", out), [], what)

    def test_the_runs_hold_per_view_state(self):
        self.assertIn("8 views, 3 per iteration", self.stderr["cv"])
        self.assertIn("ReSTIR reuses light samples", self.stderr["restir"])
        for variant, kinds in (("cv", ["cv.state", "view.theta"]),
                               ("restir", ["cv.state", "view.theta", "restir.reservoirs"])):
            r = subprocess.run([TANDEM, "checkpoint",
                                str(self.work / variant / "whole" / "checkpoint.bin")],
                               capture_output=True, text=True)
            self.assertEqual(r.returncode, 0, r.stderr)
            for kind in kinds:
                for k in range(VIEWS):
                    self.assertIn(f"  section state:{kind}.view{k} ", r.stdout, variant)

    def test_kill_between_checkpoints(self):
        for variant in self.VARIANTS:
            what = f"{variant}, iteration:6"
            out = self.copy(variant, None, "iteration")
            r = self.killed(variant, out, "iteration:6")  # a fresh run: the start of iteration 6
            self.assertEqual(r.returncode, -signal.SIGKILL, f"{what}: {r.stderr}")
            self.assertEqual(temporaries(out), [], what)
            self.assert_resumes_to_the_end(variant, out, what)

    def test_kill_half_way_through_a_checkpoint_write(self):
        # The first write-middle passage of the resumed interval that is the checkpoint write of
        # iteration 8: the smallest n whose kill finds that write begun (its temporary there, or
        # checkpoint.bin replaced), by bisection, as the passages come one after another.
        for variant in self.VARIANTS:
            part = self.work / variant / "part" / "checkpoint.bin"
            runs = {}  # n: (the write begun, the folder), each kill run once

            def kill(n):
                if n in runs:
                    return runs[n]
                out = self.copy(variant, "part", f"middle-{n}")
                r = self.killed(variant, out, f"write-middle:{n}", "--resume")
                self.assertIn(r.returncode, (0, -signal.SIGKILL), r.stderr)
                begun = (r.returncode == 0 or
                         "checkpoint.bin" in [target_of(t) for t in temporaries(out)] or
                         (out / "checkpoint.bin").read_bytes() != part.read_bytes())
                runs[n] = begun, out
                return runs[n]

            low, high = 0, 16  # not begun at low (no kill), begun at high
            while not kill(high)[0]:
                low, high = high, 2 * high
            while high - low > 1:
                middle = (low + high) // 2
                if kill(middle)[0]:
                    high = middle
                else:
                    low = middle
            what = f"{variant}, write-middle:{high}"
            _, out = kill(high)
            left = temporaries(out)
            self.assertEqual(len(left), 1, f"{what}: {left}")
            self.assertEqual(target_of(left[0]), "checkpoint.bin", what)
            size = (out / left[0]).stat().st_size
            whole = (self.work / variant / "whole" / "checkpoint.bin").stat().st_size
            self.assertTrue(0 < size < whole, f"{what}: {size} bytes of {whole}")
            self.assert_resumes_to_the_end(variant, out, what)

    def test_kill_while_the_previous_checkpoint_is_kept(self):
        for variant in self.VARIANTS:
            for where, left_for in (("previous-linked", ["checkpoint.bin", "checkpoint.prev.bin"]),
                                    ("previous-kept", ["checkpoint.bin"])):
                what = f"{variant}, {where}"
                out = self.copy(variant, "part", where)
                r = self.killed(variant, out, f"{where}:1", "--resume")
                self.assertEqual(r.returncode, -signal.SIGKILL, f"{what}: {r.stderr}")
                self.assertEqual([target_of(t) for t in temporaries(out)],
                                 left_for, what)
                self.assert_resumes_to_the_end(variant, out, what)

    def test_until_then_resume(self):
        for variant in self.VARIANTS:
            out = self.copy(variant, None, "until")
            r = run(self.config(variant), out, "--until", "6")
            self.assertEqual(r.returncode, 0, f"{variant}: {r.stderr}")
            r = run(self.config(variant), out, "--resume")
            self.assertEqual(r.returncode, 0, f"{variant}: {r.stderr}")
            self.assertEqual(differences(self.work / variant / "whole", out, stopped_at=6), [],
                             variant)


class Targets(unittest.TestCase):
    """Every sensor of the globe rendered at 16x16, 64 spp, as t_K.exr and t_K.png."""

    @classmethod
    def setUpClass(cls):
        cls.work = pathlib.Path(tempfile.mkdtemp(prefix="tandem-views-targets-"))
        cls.addClassCleanup(shutil.rmtree, cls.work, ignore_errors=True)  # setUpClass failing too
        cls.renders = cls.work / "renders"
        cls.renders.mkdir()
        r = subprocess.run([TANDEM, "render", str(GLOBE), "-D", "res=16", "--spp", "64",
                            "--sensor", "all", "--out", str(cls.renders / "t.exr"), "--out",
                            str(cls.renders / "t.png")], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        cls.exr = [cls.renders / f"t_{k}.exr" for k in range(VIEWS)]
        cls.png = [cls.renders / f"t_{k}.png" for k in range(VIEWS)]

    def optimize(self, name, target, **extra):
        config = base_config(target=target, iterations=2, checkpoint_every=2, **extra)
        path = self.work / f"{name}.json"
        path.write_text(json.dumps(config))
        out = self.work / name
        shutil.rmtree(out, ignore_errors=True)
        return run(path, out), path, out

    def test_render_writes_every_sensor(self):
        self.assertEqual(sorted(p.name for p in self.renders.iterdir()),
                         sorted([p.name for p in self.exr] + [p.name for p in self.png]))
        r = subprocess.run([IMGCMP, str(self.exr[0]), str(self.exr[1])], capture_output=True)
        self.assertEqual(r.returncode, 1)  # two views, two images

    def test_exr_targets_are_taken_word_for_word(self):
        r, _, out = self.optimize("exr", {"images": [str(p) for p in self.exr]})
        self.assertEqual(r.returncode, 0, r.stderr)
        pairs = [str(p) for k in range(VIEWS) for p in (self.exr[k], out / "views" / str(k) /
                                                         "target.exr")]
        r = subprocess.run([IMGCMP, *pairs], capture_output=True, text=True)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)

    def test_the_exr_reader_here_reads_what_tandem_wrote(self):
        # read_exr and write_exr against tandem-imgcmp: a copy written uncompressed stores the
        # same words as Tandem's ZIP-compressed file
        width, height, pixels = read_exr(self.exr[0])
        self.assertEqual((width, height, sorted(pixels)), (16, 16, ["B", "G", "R"]))
        write_exr(self.work / "copy.exr", width, height, pixels)
        self.assertTrue(kr.same_pixels(self.exr[0], self.work / "copy.exr", IMGCMP))

    def test_png_targets_agree_within_8_bit_srgb(self):
        r, _, out = self.optimize("png", {"images": [str(p) for p in self.png]})
        self.assertEqual(r.returncode, 0, r.stderr)
        step = 0.5 / 255  # half an 8-bit code, in sRGB
        differ = 0
        for k in range(VIEWS):
            _, _, exact = read_exr(self.exr[k])
            _, _, got = read_exr(out / "views" / str(k) / "target.exr")
            for channel in "RGB":
                for i, (x, y) in enumerate(zip(exact[channel], got[channel])):
                    e = srgb_encode(x)
                    # the interval of linear values whose code rounds as x's may, half a step
                    # either side in sRGB; float32 rounding of the decoded value aside
                    low = srgb_decode(max(e - step, 0.0))
                    high = srgb_decode(min(e + step, 1.0))
                    slack = 1e-6 * max(abs(y), 1e-3)
                    self.assertTrue(low - slack <= y <= high + slack,
                                    f"view {k}, {channel} of pixel {i}: {y} for {x}, outside "
                                    f"[{low}, {high}]")
                    differ += x != y
        self.assertGreater(differ, 0)  # the PNGs were quantised, and so read

    def assert_refused(self, r, file, *words):
        self.assertEqual(r.returncode, 1, r.stderr)
        lines = r.stderr.strip().splitlines()
        self.assertEqual(len(lines), 1, r.stderr)
        self.assertTrue(lines[0].startswith(f"tandem: error: {file}: "), r.stderr)
        for w in words:
            self.assertIn(w, lines[0])

    def test_bad_targets_are_one_line_naming_the_file(self):
        exr = [str(p) for p in self.exr]
        small = self.work / "small"
        small.mkdir(exist_ok=True)
        r = subprocess.run([TANDEM, "render", str(GLOBE), "-D", "res=8", "--spp", "4", "--sensor",
                            "3", "--out", str(small / "t_3.exr")], capture_output=True, text=True)
        self.assertEqual(r.returncode, 0, r.stderr)
        nan = small / "nan_2.exr"
        width, height, pixels = read_exr(self.exr[2])
        pixels["G"][11 * width + 5] = math.nan  # column 5, row 11
        write_exr(nan, width, height, pixels)
        missing = self.work / "nowhere" / "t_5.exr"
        cases = [
            ("seven", {"images": exr[:7]}, {}, None,
             ["target.images has 7 images, the scene has 8 sensors"]),
            ("size", {"images": exr[:3] + [str(small / "t_3.exr")] + exr[4:]}, {},
             small / "t_3.exr", ["the target is 8x8, sensor 3 ('view3') renders 16x16"]),
            ("missing", {"images": exr[:5] + [str(missing)] + exr[6:]}, {}, missing, []),
            ("nan", {"images": exr[:2] + [str(nan)] + exr[3:]}, {}, nan,
             ["the texel at column 5, row 11 (from the top left, from 0) is not finite"]),
            ("masks", {"images": exr, "masks": [str(p) for p in self.png[:7]]}, {}, None,
             ["target.masks has 7 files, target.images 8"]),
            ("batch", {"images": exr}, {"batch": 9}, None, ["'batch' is 9", "8 views"]),
        ]
        for name, target, extra, file, words in cases:
            with self.subTest(name):
                r, config, out = self.optimize(f"bad-{name}", target, **extra)
                self.assert_refused(r, file or config, *words)
                self.assertFalse((out / "checkpoint.bin").exists())

    def test_an_unknown_sensor_is_refused_naming_the_sensors(self):
        r = subprocess.run([TANDEM, "render", str(GLOBE), "-D", "res=16", "--sensor", "nope",
                            "--out", str(self.work / "nope.exr")], capture_output=True, text=True)
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertEqual(r.stderr.strip().splitlines(), [
            "tandem: error: no sensor 'nope': the scene has 8 sensors: " +
            ", ".join(f"{k} ('view{k}')" for k in range(VIEWS))])
        self.assertFalse((self.work / "nope.exr").exists())


if __name__ == "__main__":
    TANDEM = sys.argv.pop(1)
    IMGCMP = sys.argv.pop(1)
    unittest.main(verbosity=2)
