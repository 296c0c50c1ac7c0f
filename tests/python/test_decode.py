"""Python.DecodeEqualsTheCApi: the package's frames are the C API's, bit for bit.

Each golden file decoded at 20 times over its whole range (extrapolation included) by c_frames (a C
player of libfacemorph_decoder.so.1) and by facemorph.File.decode: every array's bytes the same; the
same from bytes as from a path; the texture blend rebuilt from texture_weights and keyframe_texture.
"""

import os
import threading
import unittest

import numpy as np

import support
import facemorph


class DecodeEqualsTheCApi(unittest.TestCase):
    def test_golden_files_at_20_times_bit_for_bit(self):
        for path in support.GOLDEN:
            with self.subTest(file=os.path.basename(path)):
                reference = support.c_frames(path, 20)
                self.assertEqual(len(reference), 20)
                with facemorph.open(path) as f:
                    begin, end = f.info["range"]
                    for expected, t in zip(reference, support.times(begin, end, 20)):
                        self.assertEqual(t, expected["t"])
                        frame = f.decode(t)
                        self.assertEqual(frame.time, t)
                        self.assertEqual((frame.vertex_count, frame.triangle_count, frame.texture_size),
                                         (expected["vertex_count"], expected["triangle_count"], expected["texture_size"]))
                        self.assertEqual(frame.positions.shape, (frame.vertex_count, 3))
                        self.assertEqual(frame.positions.dtype, np.float32)
                        self.assertEqual(frame.faces.dtype, np.int32)
                        self.assertTrue(frame.positions.flags.c_contiguous and frame.positions.flags.owndata)
                        self.assertEqual(frame.positions.tobytes(), expected["positions"], f"positions at t = {t}")
                        self.assertEqual(frame.normals.tobytes(), expected["normals"], f"normals at t = {t}")
                        self.assertEqual(frame.uv.tobytes(), expected["uv"], f"uv at t = {t}")
                        self.assertEqual(frame.faces.tobytes(), expected["faces"], f"faces at t = {t}")
                        rgba = np.frombuffer(expected["texture"], np.uint8).reshape(frame.texture_size, frame.texture_size, 4)
                        self.assertTrue(np.all(rgba[:, :, 3] == 255))
                        self.assertEqual(frame.texture.shape, (frame.texture_size, frame.texture_size, 3))
                        self.assertEqual(frame.texture.tobytes(), np.ascontiguousarray(rgba[:, :, :3]).tobytes(), f"texture at t = {t}")

    def test_bytes_decode_as_the_path_does(self):
        path = support.GOLDEN[1]
        with open(path, "rb") as raw:
            data = raw.read()
        with facemorph.open(path) as by_path, facemorph.open(bytearray(data)) as by_bytes:
            self.assertEqual(by_bytes.name, "memory")
            info_path, info_bytes = by_path.info, by_bytes.info
            self.assertEqual(info_path, info_bytes)
            for t in support.times(*info_path["range"], 7):
                a, b = by_path.decode(t), by_bytes.decode(t)
                for name in facemorph.OUTPUTS:
                    self.assertEqual(getattr(a, name).tobytes(), getattr(b, name).tobytes(), name)

    def test_info_holds_the_header(self):
        with facemorph.open(support.GOLDEN[1]) as f:
            info = f.info
            self.assertEqual(info["format_version"], "2.1")
            self.assertEqual(info["keyframe_count"], len(info["keyframe_times"]))
            self.assertEqual(list(f.keyframe_times), info["keyframe_times"])
            self.assertGreater(info["grid_n"], 0)
            self.assertEqual(info["texture_codec"], "avif")
            self.assertIsInstance(info["settings"], dict)
            self.assertIn("keyframes", info["settings"])
            self.assertIn("nose_tip", info["landmark_names"])
            self.assertTrue(info["encoder"].startswith("facemorph "))
            info["settings"]["keyframes"] = "changed"  # a copy: the file's stays
            self.assertNotEqual(f.info["settings"]["keyframes"], "changed")

    def test_format_2_6_opens_as_2_6(self):
        # golden_v2_6's positions are under the levels predictor (a KGLV chunk, spec/container.md
        # §7.2): the package's decoder reads 2.6, and the bit-for-bit test above decodes it.
        with facemorph.open(support.GOLDEN[3]) as f:
            self.assertEqual(f.info["format_version"], "2.6")
            self.assertEqual(f.info["grid_n"], 129)
            self.assertEqual(f.info["keyframe_count"], 2)

    def test_outputs_and_flags(self):
        with facemorph.open(support.GOLDEN[0]) as f:
            t = f.info["keyframe_times"][1] * 0.7
            whole = f.decode(t)
            only = f.decode(t, outputs=("positions",))
            self.assertEqual(only.positions.tobytes(), whole.positions.tobytes())
            self.assertIsNone(only.normals)
            self.assertIsNone(only.texture)
            flipped = f.decode(t, flip_v=True, outputs=["uv"])
            np.testing.assert_allclose(flipped.uv[:, 1], 1 - whole.uv[:, 1], atol=1e-6)
            with self.assertRaises(facemorph.InvalidArgumentError):
                f.decode(t, outputs=("colour",))
            end = f.info["range"][1]
            clamped = f.decode(end + 10, clamp=True)
            self.assertEqual(clamped.time, end)
            self.assertEqual(clamped.positions.tobytes(), f.decode(end).positions.tobytes())

    def test_texture_weights_rebuild_the_texture(self):
        # Each keyframe's texture (keyframe_texture, the file's reader) and the weights at t (the C
        # API) make the decoder's texture byte for byte, as texture_weights documents; 2.2 shares.
        for path in support.GOLDEN[1:]:
            with self.subTest(file=os.path.basename(path)), facemorph.open(path) as f:
                times = f.info["keyframe_times"]
                textures = [f.keyframe_texture(k) for k in range(len(times))]
                for k, t in enumerate(times):
                    keys, weights = f.texture_weights(t)
                    self.assertEqual(list(weights), [1.0])
                    self.assertEqual(f.decode(t).texture.tobytes(), textures[keys[0]].tobytes())
                span = times[-1] - times[0]
                for t in (times[0] + 0.13 * span, times[0] + 0.5 * span, f.info["range"][1]):
                    keys, weights = f.texture_weights(t)
                    self.assertGreaterEqual(len(keys), 2)
                    self.assertAlmostEqual(float(weights.sum()), 1.0, places=12)
                    blended = np.zeros(textures[0].shape, np.float32)
                    for k, w in zip(keys, weights):
                        blended += np.float32(w) * textures[k].astype(np.float32)
                    rebuilt = np.clip(blended + np.float32(0.5), 0, 255).astype(np.uint8)
                    self.assertEqual(rebuilt.tobytes(), f.decode(t).texture.tobytes(), f"t = {t}")
                with self.assertRaises(facemorph.InvalidArgumentError):
                    f.keyframe_texture(len(times))

    def test_threads_share_a_file_and_decode_files_in_parallel(self):
        # A File per thread decodes what one thread alone decodes, bit for bit, while the others run.
        # Threads sharing one File take turns (a decoder is used by one thread at a time): their
        # frames are whole and right, to within the reconstruction's tolerance, but not bitwise the
        # one-thread sequence's (a decoder starts each frame from what it last decoded, so its bits
        # follow the order of the calls: the C API's own behaviour, spec/python.md).
        path = support.GOLDEN[1]
        with facemorph.open(path) as f:
            ts = support.times(*f.info["range"], 12)
            expected = [f.decode(t).positions for t in ts]
        diagonal = float(np.linalg.norm(expected[0].max(axis=0) - expected[0].min(axis=0)))
        shared = facemorph.open(path)
        results, errors = {}, []

        def work(index, own):
            try:
                file = facemorph.open(path) if own else shared
                for i, t in enumerate(ts):
                    results[(index, own, i)] = file.decode(t).positions
            except Exception as e:  # noqa: BLE001 (reported below)
                errors.append(e)

        threads = [threading.Thread(target=work, args=(i, i % 2 == 0)) for i in range(6)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        shared.close()
        self.assertEqual(errors, [])
        self.assertEqual(len(results), 6 * len(ts))
        for (index, own, i), positions in results.items():
            if own:
                self.assertEqual(positions.tobytes(), expected[i].tobytes(), f"thread {index}, t = {ts[i]}")
            else:
                self.assertLess(float(np.abs(positions - expected[i]).max()), 1e-4 * diagonal, f"thread {index}, t = {ts[i]}")


if __name__ == "__main__":
    support.main()
