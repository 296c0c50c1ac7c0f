#!/usr/bin/env python3
"""Makes tests/blender/data/holes.fmv: a small capture whose eyes and mouth are open holes, so the
decoder cuts them per frame and the counts change between frames (the add-on rebuilds the mesh).

    make_holes_sample.py BUILD_TOOLS_DIR OUT.fmv

fmsynth writes a closed-eyed face (8 frames, 4000 vertices, 128² texture); the faces within a
radius of each eye's and the mouth's landmarks are removed from every frame (the radius follows the
landmarks, so a mouth that opens opens its hole), and fmenc encodes the result with 40% keyframes (3 of 8).
"""

import csv
import json
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

EYES = {"right": ["right_eye_outer_corner", "right_eye_inner_corner", "right_eye_upper_lid", "right_eye_lower_lid"],
        "left": ["left_eye_outer_corner", "left_eye_inner_corner", "left_eye_upper_lid", "left_eye_lower_lid"]}
MOUTH = ["upper_lip_inner_midline", "lower_lip_inner_midline", "mouth_corner_right", "mouth_corner_left"]


def read_landmarks(path):
    frames = {}
    with open(path) as handle:
        for row in csv.DictReader(handle):
            frames.setdefault(int(row["frame"]), {})[row["name"]] = np.array([float(row[k]) for k in "xyz"])
    return frames


def holes_of(marks):
    """(centre, radius) of each hole: the eyes' corners apart, the mouth's corners apart, scaled."""
    holes = []
    for names in EYES.values():
        points = np.array([marks[n] for n in names])
        holes.append((points.mean(0), 0.35 * np.linalg.norm(points[0] - points[1])))
    points = np.array([marks[n] for n in MOUTH])
    opening = np.linalg.norm(points[0] - points[1])
    holes.append((points[:2].mean(0), max(0.18 * np.linalg.norm(points[2] - points[3]), 0.6 * opening)))
    return holes


def cut_obj(source, target, holes):
    lines = source.read_text().splitlines()
    vertices = np.array([[float(v) for v in line.split()[1:4]] for line in lines if line.startswith("v ")])
    kept = []
    for line in lines:
        if not line.startswith("f "):
            kept.append(line)
            continue
        corners = [int(token.split("/")[0]) - 1 for token in line.split()[1:]]
        centre = vertices[corners].mean(0)
        if all(np.linalg.norm(centre - c) > r for c, r in holes):
            kept.append(line)
    target.write_text("\n".join(kept) + "\n")


def main():
    tools, out = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
    with tempfile.TemporaryDirectory() as work:
        capture = pathlib.Path(work) / "capture"
        subprocess.run([tools / "fmsynth", "-o", capture, "--frames", "8", "--vertices", "4000", "--texture-size", "128",
                        "--expression", "talk", "-q"], check=True)
        landmarks = read_landmarks(capture / "landmarks.csv")
        for index, frame in enumerate(json.loads((capture / "capture.json").read_text())["frames"]):
            mesh = capture / frame["mesh"]
            cut_obj(mesh, mesh, holes_of(landmarks[index]))
        subprocess.run([tools / "fmenc", capture, "-o", out, "--keyframes", "40%", "-q"], check=True)
    print(out)


if __name__ == "__main__":
    main()
