"""Python.CommandLine: python3 -m facemorph info|decode|encode, as fminfo, fmdec and fmenc do in brief,
and their failures: the library's message on stderr, status 1."""

import filecmp
import json
import os
import subprocess
import sys
import unittest

import numpy as np

import support
import facemorph

GOLDEN = support.GOLDEN[1]


def cli(*args, ok=True):
    result = subprocess.run([sys.executable, "-m", "facemorph", *map(str, args)], capture_output=True, text=True)
    if ok and result.returncode != 0:
        raise AssertionError(f"python3 -m facemorph {' '.join(map(str, args))}: {result.returncode}\n{result.stderr}")
    return result


def read_obj(path):
    v, f = [], []
    with open(path) as obj:
        for line in obj:
            if line.startswith("v "):
                v.append([float(x) for x in line.split()[1:]])
            elif line.startswith("f "):
                f.append([int(c.split("/")[0]) - 1 for c in line.split()[1:]])
    return np.array(v, np.float32), np.array(f, np.int32)


class CommandLine(unittest.TestCase):
    def test_info(self):
        text = cli("info", GOLDEN).stdout
        self.assertIn("format 2.1", text)
        self.assertIn("N = 33", text)
        self.assertIn("keyframes   3 at 0.000 0.167 0.367 s", text)
        info = json.loads(cli("info", GOLDEN, "--json").stdout)
        with facemorph.open(GOLDEN) as f:
            self.assertEqual(info["keyframe_times"], f.info["keyframe_times"])
            self.assertEqual(info["settings"], f.info["settings"])

    def test_decode_one_frame_and_a_range(self):
        out = os.path.join(support.WORK, "frame.obj")
        cli("decode", GOLDEN, "--t", "0.2", "-o", out, "-q")
        positions, faces = read_obj(out)
        with facemorph.open(GOLDEN) as f:
            frame = f.decode(0.2)
        self.assertEqual(positions.tobytes(), frame.positions.tobytes())  # %.9g: float32 exactly
        self.assertEqual(faces.tobytes(), frame.faces.tobytes())
        with open(os.path.join(support.WORK, "frame.png"), "rb") as png:
            self.assertEqual(png.read(8), b"\x89PNG\r\n\x1a\n")
        folder = os.path.join(support.WORK, "frames")
        text = cli("decode", GOLDEN, "--fps", "30", "--out-dir", folder).stdout
        self.assertIn("12 frames from 0.000 to 0.367 s", text)
        self.assertEqual(len([n for n in os.listdir(folder) if n.endswith(".obj")]), 12)

    def test_failures_name_the_file(self):
        missing = os.path.join(support.WORK, "missing.fmv")
        result = cli("info", missing, ok=False)
        self.assertEqual(result.returncode, 1)
        self.assertIn(f"facemorph: io: ", result.stderr)
        self.assertIn(missing, result.stderr)
        result = cli("decode", GOLDEN, "--t", "99", "-o", os.path.join(support.WORK, "x.obj"), ok=False)
        self.assertEqual(result.returncode, 1)
        self.assertIn("out-of-range", result.stderr)
        result = cli("info", GOLDEN, "--max-memory", "1M", ok=False)
        self.assertIn("limit", result.stderr)
        self.assertIn("max_memory_bytes", result.stderr)
        self.assertEqual(cli("decode", ok=False).returncode, 2)

    def test_encode_as_fmenc(self):
        try:
            import facemorph._encoder  # noqa: F401
            capture = support.synthetic_capture("cli", "--frames", "6", "--vertices", "1200", "--texture-size", "64")
        except (ImportError, unittest.SkipTest) as e:
            self.skipTest(f"no encoder or tools: {e}")
        ours = os.path.join(support.WORK, "cli.fmv")
        text = cli("encode", capture, "-o", ours, "--keyframes", "34%", "--threads", "2").stdout
        self.assertIn("6 frames", text)
        theirs = os.path.join(support.WORK, "cli_fmenc.fmv")
        support.run(support.tool("fmenc"), capture, "-o", theirs, "-q", "--keyframes", "34%", "--threads", "2")
        self.assertTrue(filecmp.cmp(ours, theirs, shallow=False))


if __name__ == "__main__":
    support.main()
