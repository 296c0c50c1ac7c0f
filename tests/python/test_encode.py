"""Python.EncodeFromNumpyEqualsFmenc: facemorph.encode makes fmenc's bytes (cmp) from the same frames
given as numpy arrays (never written by the caller), and from the capture folder; options reach the
encoder as fmenc's do; the encoder's errors, progress and cancellation reach Python."""

import csv
import filecmp
import json
import os
import unittest

import numpy as np

import support
import facemorph

support.require_encoder_and_tools()


def numpy_frames(capture, colours_as_uint8=False):
    """The capture's frames as numpy arrays (read by the encoder's own readers), with their times and
    landmarks: what a researcher holds in memory."""
    with open(os.path.join(capture, "capture.json")) as f:
        manifest = json.load(f)
    frames, images = [], {}
    for entry in manifest["frames"]:
        mesh = facemorph.read_mesh(os.path.join(capture, entry["mesh"]))
        frame = {"vertices": mesh["vertices"], "faces": mesh["faces"], "time": entry["time"]}
        if mesh["uv"] is not None:
            frame["uv"], frame["uv_faces"] = mesh["uv"], mesh["uv_faces"]
        if mesh["texture_path"]:
            path = mesh["texture_path"]
            if path not in images:  # one image file, one array: frames sharing it pass the same array
                images[path] = facemorph.read_image(path)
            frame["texture"] = images[path]
        if mesh["colours"] is not None:
            frame["colours"] = np.rint(mesh["colours"] * 255).astype(np.uint8) if colours_as_uint8 else mesh["colours"]
        frames.append(frame)
    landmarks = {}
    csv_path = os.path.join(capture, manifest.get("landmarks_csv", "landmarks.csv"))
    if os.path.exists(csv_path):
        with open(csv_path) as f:
            for row in csv.DictReader(f):
                column = landmarks.setdefault(row["name"], np.full((len(frames), 3), np.nan))
                column[int(row["frame"])] = [float(row["x"]), float(row["y"]), float(row["z"])]
    return frames, manifest, landmarks


def fmenc(capture, out, *options):
    support.run(support.tool("fmenc"), capture, "-o", out, "-q", "--threads", "2", *options)
    return out


def same_bytes(a, b):
    return filecmp.cmp(a, b, shallow=False)


class EncodeFromNumpy(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.textured = support.synthetic_capture("textured", "--frames", "10", "--vertices", "2000", "--texture-size", "128")
        cls.coloured = support.synthetic_capture("coloured", "--frames", "8", "--vertices", "1500", "--vertex-colour", "--seed", "3")
        cls.reference = fmenc(cls.textured, os.path.join(support.WORK, "textured_fmenc.fmv"))

    def out(self, name):
        path = os.path.join(support.WORK, name)
        if os.path.exists(path):
            os.remove(path)
        return path

    def test_textured_frames_with_landmarks(self):
        frames, manifest, landmarks = numpy_frames(self.textured)
        self.assertTrue(landmarks)
        stages = []
        report = facemorph.encode(frames, self.out("textured_numpy.fmv"), fps=manifest["fps"], units=manifest["units"],
                                  landmarks=landmarks, threads=2, progress=lambda stage, done, total: stages.append(stage))
        self.assertTrue(same_bytes(report["output"], self.reference), "numpy frames vs fmenc on the capture")
        self.assertEqual(report["bytes"], os.path.getsize(self.reference))
        self.assertEqual(report["frames"], 10)
        self.assertEqual(report["dropped"], [])
        for stage in ("writing", "mapping", "registering", "keyframes"):
            self.assertIn(stage, stages)
        with facemorph.open(report["output"]) as f:
            self.assertEqual(f.info["keyframe_times"], report["keyframe_times"])
            self.assertEqual(f.info["settings"], report["settings"])
            self.assertEqual(f.info["landmark_names"], list(landmarks))

    def test_the_capture_folder(self):
        report = facemorph.encode(self.textured, self.out("textured_folder.fmv"), threads=2)
        self.assertTrue(same_bytes(report["output"], self.reference))

    def test_a_changed_vertex_changes_the_file(self):
        # The comparison above is not vacuous: one vertex 0.1 mm off makes other bytes.
        frames, manifest, landmarks = numpy_frames(self.textured)
        frames[4]["vertices"] = frames[4]["vertices"].copy()
        frames[4]["vertices"][100] += 1e-4
        report = facemorph.encode(frames, self.out("textured_moved.fmv"), fps=manifest["fps"], landmarks=landmarks, threads=2)
        self.assertFalse(same_bytes(report["output"], self.reference))

    def test_vertex_colours_and_options_as_fmenc(self):
        # Colours as uint8 arrays, no landmarks given (found from the geometry, as fmenc --landmarks
        # auto), times from the frames, and options that change the file.
        frames, manifest, _ = numpy_frames(self.coloured, colours_as_uint8=True)
        self.assertIn("colours", frames[0])
        options = ["--landmarks", "auto", "--keyframes", "25%", "--quality", "70", "--texture-codec", "webp", "--grid", "33"]
        reference = fmenc(self.coloured, os.path.join(support.WORK, "coloured_fmenc.fmv"), *options)
        report = facemorph.encode(frames, self.out("coloured_numpy.fmv"), keyframes="25%", quality=70, texture_codec="webp", grid=33,
                                  threads=2)
        self.assertTrue(same_bytes(report["output"], reference))
        self.assertEqual(report["grid_n"], 33)
        self.assertEqual(report["settings"]["texture_codec"], "webp")
        default = facemorph.encode(frames, self.out("coloured_default.fmv"), threads=2)
        self.assertFalse(same_bytes(default["output"], reference))

    def test_a_frame_that_cannot_be_encoded(self):
        frames, manifest, _ = numpy_frames(self.coloured)
        f = frames[3]
        n = len(f["vertices"])
        frames[3] = {"vertices": np.concatenate([f["vertices"], [[5, 5, 5], [5, 6, 5], [6, 5, 5]]]),
                     "faces": np.concatenate([f["faces"], [[n, n + 1, n + 2]]]),
                     "colours": np.concatenate([f["colours"], np.zeros((3, 3))]), "time": f["time"]}
        with self.assertRaises(facemorph.Error) as caught:
            facemorph.encode(frames, self.out("strict.fmv"), strict=True, threads=2)
        self.assertIsInstance(caught.exception, (facemorph.NotADiskError, facemorph.InvalidMeshError))
        self.assertIn("frame_0003", str(caught.exception))
        self.assertFalse(os.path.exists(os.path.join(support.WORK, "strict.fmv")))
        report = facemorph.encode(frames, self.out("dropped.fmv"), threads=2)
        self.assertEqual([d["frame"] for d in report["dropped"]], [3])
        self.assertIn("frame_0003", report["dropped"][0]["name"])
        self.assertEqual(report["settings"]["dropped_frames"][0]["frame"], 3)

    def test_progress_can_stop_the_encode(self):
        frames, manifest, _ = numpy_frames(self.coloured)

        class Stop(Exception):
            pass

        def progress(stage, done, total):
            if stage == "registering":
                raise Stop("enough")

        out = self.out("stopped.fmv")
        with self.assertRaises(Stop):
            facemorph.encode(frames, out, progress=progress, threads=2)
        self.assertFalse(os.path.exists(out))
        with self.assertRaises(Stop):  # between the frames written for the encoder
            facemorph.encode(frames, out, progress=lambda stage, done, total: (_ for _ in ()).throw(Stop()), threads=2)
        self.assertFalse(os.path.exists(out))

    def test_bad_arrays_and_options_are_named(self):
        frames, manifest, _ = numpy_frames(self.coloured)
        out = self.out("bad.fmv")
        cases = [
            ([{**frames[0], "vertices": frames[0]["vertices"][:, :2]}] + frames[1:], {}, "frame 0 vertices"),
            ([{**frames[0], "faces": frames[0]["faces"] + len(frames[0]["vertices"])}] + frames[1:], {}, "frame 0 faces"),
            ([{**frames[0], "colours": frames[0]["colours"][:5]}] + frames[1:], {}, "frame 0 colours"),
            ([{**frames[0], "texture": np.zeros((4, 4, 3), np.uint8)}] + frames[1:], {}, "needs uv"),
            (frames, {"keyframes": "150%"}, "keyframes"),
            (frames, {"keyframes": "10%", "max_error": 0.01}, "not both"),
            (frames, {"registration": "magic"}, "magic"),
            (frames, {"quality": 500}, "quality"),
            ([], {}, "no frames"),
        ]
        for given, options, text in cases:
            with self.subTest(text=text):
                with self.assertRaises(facemorph.InvalidArgumentError) as caught:
                    facemorph.encode(given, out, **options)
                self.assertIn(text, str(caught.exception))
        self.assertFalse(os.path.exists(out))
        with self.assertRaises(facemorph.IoError):
            facemorph.encode(os.path.join(support.WORK, "no such capture"), out)


if __name__ == "__main__":
    support.main()
