"""Decode time a frame through Python (facemorph.File.decode) against the C API (c_frames, a C player
of libfacemorph_decoder.so.1), on the same file at the same times with the same outputs (positions,
normals, UVs, faces, texture). Not a test: a measurement (spec/python.md §6).

    python3 python/bench/bench_decode.py FILE.fmv --c-frames build/tests/python/python_c_frames \
        [--frames 120] [--passes 5]

Each pass decodes FILE at --frames times spread over its range, in order, on one decoder (the first
pass also decodes the keyframes). The C and Python runs alternate pass by pass so that the machine's
load falls on both alike. Prints each pass's mean ms a frame and the ratio Python / C of the medians
of the warm passes (all but the first).
"""

import argparse
import os
import statistics
import subprocess
import sys
import time

import facemorph


def python_passes(path, frames, passes):
    out = []
    with facemorph.open(path) as f:
        begin, end = f.range
        ts = [begin + (end - begin) * i / (frames - 1) for i in range(frames)]
        for _ in range(passes):
            start = time.perf_counter()
            for t in ts:
                f.decode(t)
            out.append(1000 * (time.perf_counter() - start) / frames)
    return out


def c_passes(c_frames, path, frames, passes):
    result = subprocess.run([c_frames, path, str(frames), "-", str(passes)], check=True, capture_output=True, text=True)
    return [float(x) for x in result.stdout.split()]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("file")
    parser.add_argument("--c-frames", required=True, help="build/tests/python/python_c_frames")
    parser.add_argument("--frames", type=int, default=120)
    parser.add_argument("--passes", type=int, default=5)
    parser.add_argument("--rounds", type=int, default=3, help="C and Python runs, alternating")
    args = parser.parse_args()
    with facemorph.open(args.file) as f:
        info = f.info
    print(f"{args.file}: N = {info['grid_n']}, {info['grid_vertex_count']} vertices, texture {info['texture_size']}², "
          f"{info['keyframe_count']} keyframes; {args.frames} frames a pass, {args.passes} passes, {args.rounds} rounds")
    c_warm, py_warm = [], []
    for r in range(args.rounds):
        c = c_passes(args.c_frames, args.file, args.frames, args.passes)
        py = python_passes(args.file, args.frames, args.passes)
        print(f"round {r}: C      ms a frame " + " ".join(f"{x:7.3f}" for x in c))
        print(f"round {r}: Python ms a frame " + " ".join(f"{x:7.3f}" for x in py))
        c_warm += c[1:]
        py_warm += py[1:]
    c_median, py_median = statistics.median(c_warm), statistics.median(py_warm)
    print(f"warm passes: C {c_median:.3f} ms, Python {py_median:.3f} ms a frame (medians): Python / C = {py_median / c_median:.3f}")


if __name__ == "__main__":
    sys.exit(main())
