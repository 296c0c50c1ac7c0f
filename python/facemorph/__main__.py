"""``python3 -m facemorph info|decode|encode``: fminfo, fmdec and fmenc in brief, through the package.

    python3 -m facemorph info face.fmv [--json]
    python3 -m facemorph decode face.fmv --t 1.45 -o frame.obj        # + frame.mtl, frame.png
    python3 -m facemorph decode face.fmv --fps 30 --out-dir frames/   # every frame at 30 fps
    python3 -m facemorph encode CAPTURE_DIR -o face.fmv [--keyframes 10%] [--max-error 0.5%] ...

Errors are printed on stderr as ``facemorph: STATUS: MESSAGE`` (the library's message names the
file) and exit with status 1; a bad command line exits with 2.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import struct
import sys
import time
import zlib
from typing import List, Optional

import numpy as np

from . import decode as _decode
from .errors import Error, InvalidArgumentError


def _limits(args: argparse.Namespace) -> dict:
    return {"max_memory": args.max_memory, "max_work": args.max_work}


def _add_limits(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--max-memory", help="what the file and its decoder may hold (bytes, or 64M, 1G; default 256M)")
    parser.add_argument("--max-work", type=int, help="work units one frame may take (default 16000000, about a second; 0: no bound)")


# --- info ----------------------------------------------------------------------------------------

def _info(args: argparse.Namespace) -> int:
    with _decode.open(args.file, **_limits(args)) as f:
        info = f.info
    if args.json:
        info["range"] = list(info["range"])
        info["range"] = [x if math.isfinite(x) else str(x) for x in info["range"]]
        print(json.dumps(info, indent=1))
        return 0
    begin, end = info["range"]
    print(f"file        {args.file}: {info['file_bytes']} bytes, format {info['format_version']}, written by {info['encoder']}")
    print(f"capture     {info['duration'] + 1 / info['fps']:.3f} s at {info['fps']:.3f} fps (frames at {info['first_time']:.3f} .. "
          f"{info['last_time']:.3f} s), units {info['units']}")
    print(f"grid        N = {info['grid_n']}: {info['grid_vertex_count']} vertices, {info['grid_triangle_count']} triangles"
          f"{', holes cut per frame' if info['has_holes'] else ''}")
    print(f"range       decodes t in [{begin:.3f}, {end:.3f}] s")
    if info["texture_size"]:
        print(f"texture     {info['texture_size']}x{info['texture_size']} {info['texture_codec'].upper()}, "
              f"{info['distinct_textures']} stored for {info['keyframe_count']} keyframes")
    else:
        print("texture     none")
    print(f"landmarks   {len(info['landmark_names'])} names")
    print(f"keyframes   {info['keyframe_count']} at " + " ".join(f"{t:.3f}" for t in info["keyframe_times"]) + " s")
    print(f"settings    {info['settings_text']}")
    return 0


# --- decode --------------------------------------------------------------------------------------

def _png(path: str, image: np.ndarray) -> None:
    """An RGB8 image as a PNG file (zlib alone: no imaging library needed)."""
    height, width, _ = image.shape
    rows = np.concatenate([np.zeros((height, 1), np.uint8), image.reshape(height, width * 3)], axis=1)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
                + chunk(b"IDAT", zlib.compress(rows.tobytes(), 6)) + chunk(b"IEND", b""))


def _write_obj(path: str, frame) -> None:
    """The frame as OBJ (positions, normals, UVs, faces), with an MTL and the texture as PNG beside it."""
    stem = os.path.splitext(path)[0]
    lines: List[str] = ["# facemorph"]
    if frame.texture is not None:
        _png(stem + ".png", frame.texture)
        with open(stem + ".mtl", "w") as m:
            m.write(f"# facemorph\nnewmtl face\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nillum 1\nmap_Kd {os.path.basename(stem)}.png\n")
        lines += [f"mtllib {os.path.basename(stem)}.mtl", "usemtl face"]
    # %.9g: a float32 reads back to the same float32.
    lines += ["v %.9g %.9g %.9g" % tuple(p) for p in frame.positions.tolist()]
    lines += ["vn %.9g %.9g %.9g" % tuple(n) for n in frame.normals.tolist()]
    lines += ["vt %.9g %.9g" % tuple(uv) for uv in frame.uv.tolist()]
    lines += ["f {0}/{0}/{0} {1}/{1}/{1} {2}/{2}/{2}".format(*(face + 1)) for face in frame.faces]
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def _decode_command(args: argparse.Namespace) -> int:
    if (args.t is None) == (args.fps is None):
        raise InvalidArgumentError("decode: --t T (one frame) or --fps F (a range), one of them")
    flags = {"clamp": args.clamp, "keep_holes_filled": args.keep_holes_filled}
    outputs = None if not args.no_texture else ("positions", "normals", "uv", "faces")
    with _decode.open(args.file, **_limits(args)) as f:
        if args.t is not None:
            if not args.output:
                raise InvalidArgumentError("decode --t: -o FRAME.obj is needed")
            frame = f.decode(args.t, outputs=outputs, **flags)
            _write_obj(args.output, frame)
            if not args.quiet:
                print(f"facemorph: t = {frame.time:.4f} s -> {args.output}: {frame.vertex_count} vertices, {frame.triangle_count} faces, "
                      f"{frame.iterations} iterations" + (" (did not converge)" if frame.fell_back else ""))
            return 0
        begin, end = f.range
        first = args.begin if args.begin is not None else max(begin, f.info["first_time"])
        last = args.end if args.end is not None else min(end, f.info["last_time"])
        count = int(math.floor((last - first) * args.fps + 1e-9)) + 1
        if not args.out_dir and not args.null:
            raise InvalidArgumentError("decode --fps: --out-dir DIR or --null")
        if args.out_dir:
            os.makedirs(args.out_dir, exist_ok=True)
        start = time.perf_counter()
        for i in range(count):
            t = first + i / args.fps
            frame = f.decode(t, outputs=outputs, **flags)
            if args.out_dir:
                _write_obj(os.path.join(args.out_dir, f"frame_{i:05d}.obj"), frame)
        seconds = time.perf_counter() - start
        if not args.quiet:
            where = args.out_dir or "nowhere (--null)"
            print(f"facemorph: {count} frames from {first:.3f} to {first + (count - 1) / args.fps:.3f} s -> {where}, "
                  f"{1000 * seconds / max(count, 1):.2f} ms a frame")
    return 0


# --- encode --------------------------------------------------------------------------------------

def _encode_command(args: argparse.Namespace) -> int:
    from .encode import encode

    last_stage = [None]

    def progress(stage: str, done: int, total: int) -> None:
        if args.quiet or not sys.stderr.isatty():
            return
        if stage != last_stage[0] and last_stage[0] is not None:
            sys.stderr.write("\n")
        last_stage[0] = stage
        sys.stderr.write(f"\rfacemorph encode {stage}: {done}/{total}")
        sys.stderr.flush()

    def auto_or_int(text: Optional[str]):
        if text is None or text == "auto":
            return "auto"
        try:
            return int(text)
        except ValueError:
            raise InvalidArgumentError(f"'{text}' is neither auto nor a whole number") from None

    options = dict(fps=args.fps, landmarks=args.landmarks, keyframes=args.keyframes, max_error=args.max_error, grid=auto_or_int(args.grid),
                   texture=not args.no_texture, texture_size=auto_or_int(args.texture), quality=auto_or_int(args.quality),
                   texture_codec=args.texture_codec, registration=args.registration, spline=args.spline,
                   representation=args.representation, reference=args.reference, strict=args.strict, threads=args.threads,
                   progress=progress)
    report = encode(args.capture, args.output, **options)
    if last_stage[0] is not None:
        sys.stderr.write("\n")
    if not args.quiet:
        print(f"facemorph: {report['output']}: {report['frames']} frames, {len(report['keyframe_times'])} keyframes at "
              + " ".join(f"{t:.3f}" for t in report["keyframe_times"]) + " s")
        print(f"  grid N = {report['grid_n']}, {report['representation']}, "
              + (f"{report['texture_size']}x{report['texture_size']} texture" if report["texture_size"] else "no texture")
              + f"; {report['bytes']} bytes, {report['seconds']:.1f} s")
        print(f"  predicted worst error between keyframes: {100 * report['predicted_worst_error']:.3f}% of the bbox diagonal")
        for d in report["dropped"]:
            print(f"  dropped {d['name']} (frame {d['frame']}, {d['time']:.3f} s): {d['reason']}")
        for warning in report["warnings"]:
            print(f"  warning: {warning}")
    return 0


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="python3 -m facemorph", description="facemorph files from Python: info, decode, encode.")
    commands = parser.add_subparsers(dest="command", required=True)

    info = commands.add_parser("info", help="what a .fmv file holds (as fminfo, in brief)")
    info.add_argument("file")
    info.add_argument("--json", action="store_true", help="File.info as JSON")
    _add_limits(info)

    dec = commands.add_parser("decode", help="a frame at --t, or every frame at --fps (as fmdec, in brief)")
    dec.add_argument("file")
    dec.add_argument("--t", type=float, help="the time to decode, seconds")
    dec.add_argument("-o", "--output", help="with --t: FRAME.obj (+ FRAME.mtl, FRAME.png)")
    dec.add_argument("--fps", type=float, help="a range of frames at this rate")
    dec.add_argument("--from", dest="begin", type=float, help="with --fps: the first time (default the first frame's)")
    dec.add_argument("--to", dest="end", type=float, help="with --fps: the last time (default the last frame's)")
    dec.add_argument("--out-dir", help="with --fps: one OBJ a frame")
    dec.add_argument("--null", action="store_true", help="with --fps: decode, write nothing, print the time a frame")
    dec.add_argument("--clamp", action="store_true", help="clamp t into the file's range")
    dec.add_argument("--keep-holes-filled", action="store_true", help="eyes and mouth filled")
    dec.add_argument("--no-texture", action="store_true", help="geometry only")
    dec.add_argument("-q", "--quiet", action="store_true")
    _add_limits(dec)

    enc = commands.add_parser("encode", help="a capture into a .fmv file (as fmenc, in brief)")
    enc.add_argument("capture", help="a capture folder (capture.json), or a plain folder of meshes with --fps")
    enc.add_argument("-o", "--output", required=True)
    enc.add_argument("--fps", type=float, help="frame rate of a plain folder of meshes")
    enc.add_argument("--landmarks", help="landmarks CSV of a plain folder, or auto")
    enc.add_argument("--keyframes", help="keyframe budget, e.g. 10%% or 0.1")
    enc.add_argument("--max-error", help="instead: the predicted error bound (of the bbox diagonal), e.g. 0.5%%")
    enc.add_argument("--grid", help="N, or auto")
    enc.add_argument("--texture", help="texels per side, or auto")
    enc.add_argument("--no-texture", action="store_true", help="geometry only")
    enc.add_argument("--quality", help="texture quality 0..100 (101: lossless WebP), or auto")
    enc.add_argument("--texture-codec", default="avif", choices=["avif", "webp"])
    enc.add_argument("--registration", default="gmf", choices=["moebius", "gmf", "frame"])
    enc.add_argument("--spline", default="catmull-rom", choices=["catmull-rom", "local", "not-a-knot", "linear"])
    enc.add_argument("--representation", default="auto", choices=["auto", "hl+t", "hl", "xyz"])
    enc.add_argument("--reference", type=int, default=0, help="the frame every other is registered to")
    enc.add_argument("--strict", action="store_true", help="end at the first frame that cannot be encoded")
    enc.add_argument("--threads", type=int, default=0, help="worker threads (0: one per core)")
    enc.add_argument("-q", "--quiet", action="store_true")

    args = parser.parse_args(argv)
    try:
        if args.command == "info":
            return _info(args)
        if args.command == "decode":
            return _decode_command(args)
        return _encode_command(args)
    except Error as e:
        print(f"facemorph: {e.status}: {e}", file=sys.stderr)
        return 1
    except OSError as e:  # writing the outputs
        print(f"facemorph: {e}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
