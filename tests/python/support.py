"""What the Python package's tests share (tests/python/CMakeLists.txt runs each file through run.sh)."""

import os
import struct
import subprocess
import sys
import unittest

import numpy as np

DATA = os.environ["FACEMORPH_TEST_DATA"]          # tests/data: the golden files
WORK = os.environ["FACEMORPH_TEST_WORK"]          # a folder of this test's own
C_FRAMES = os.environ.get("FACEMORPH_C_FRAMES")   # tests/python/c_frames.c, built against the shared library
TOOLS = os.environ.get("FACEMORPH_TOOLS")         # build/tools (fmsynth, fmenc), where built
# 2.6 (N = 129, its positions in a KGLV: the levels predictor) beside the first three layouts.
GOLDEN = [os.path.join(DATA, name) for name in ("golden_v2_0.fmv", "golden_v2_1.fmv", "golden_v2_2.fmv",
                                                "golden_v2_6.fmv")]


def tool(name):
    """The path of a command-line tool, or skips the test where the tools were not built."""
    path = os.path.join(TOOLS or "", name)
    if not TOOLS or not os.path.exists(path):
        raise unittest.SkipTest(f"{name} is not built")
    return path


def run(*command, **kwargs):
    return subprocess.run([str(c) for c in command], check=True, capture_output=True, text=True, **kwargs)


def times(begin, end, count):
    """c_frames's times: begin + (end - begin) * i / (count - 1), in the same order of operations."""
    return [begin + (end - begin) * i / (count - 1) for i in range(count)]


def c_frames(path, count):
    """Every frame c_frames decodes through the C API at `times(range, count)`: dicts of raw bytes."""
    out = os.path.join(WORK, os.path.basename(path) + ".frames")
    run(C_FRAMES, path, count, out)
    with open(out, "rb") as f:
        data = f.read()
    frames, at = [], 0
    while at < len(data):
        t, = struct.unpack_from("<d", data, at)
        n, m, size = struct.unpack_from("<3I", data, at + 8)
        at += 20
        frame = {"t": t, "vertex_count": n, "triangle_count": m, "texture_size": size}
        for name, nbytes in (("positions", 12 * n), ("normals", 12 * n), ("uv", 8 * n), ("faces", 12 * m), ("texture", 4 * size * size)):
            frame[name] = data[at:at + nbytes]
            at += nbytes
        frames.append(frame)
    return frames


def main():
    os.makedirs(WORK, exist_ok=True)
    result = unittest.main(exit=False, verbosity=2).result
    sys.exit(0 if result.wasSuccessful() else 1)


def require_encoder_and_tools():
    """Skips the whole test (exit 77) without the encoder's module or fmsynth and fmenc."""
    try:
        import facemorph._encoder  # noqa: F401
    except ImportError as e:
        print(f"SKIP: no encoder module in this build (FACEMORPH_BUILD_ENCODER=OFF?): {e}")
        sys.exit(77)
    for name in ("fmsynth", "fmenc"):
        if not TOOLS or not os.path.exists(os.path.join(TOOLS, name)):
            print(f"SKIP: {name} is not built (FACEMORPH_BUILD_TOOLS)")
            sys.exit(77)


def synthetic_capture(name, *options):
    """A small fmsynth capture in WORK (made once per test run)."""
    path = os.path.join(WORK, name)
    if not os.path.exists(os.path.join(path, "capture.json")):
        run(tool("fmsynth"), "-o", path, "-q", *options)
    return path
