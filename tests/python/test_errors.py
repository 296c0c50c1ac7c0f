"""Python.ErrorsAndLimits: each failure raises the facemorph.Error subclass of its status, with the
library's message naming the file; each limit of fm_decoder_options is applied and named."""

import math
import os
import unittest

import support
import facemorph

GOLDEN = support.GOLDEN[1]  # 2.1: N = 33, 3 keyframes, 64² AVIF texture sequence


def damaged(name, data):
    path = os.path.join(support.WORK, name)
    with open(path, "wb") as f:
        f.write(data)
    return path


class ErrorsAndLimits(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        with open(GOLDEN, "rb") as f:
            cls.data = f.read()

    def expect(self, cls, call, *named):
        with self.assertRaises(cls) as caught:
            call()
        error = caught.exception
        self.assertIs(type(error), cls)
        self.assertIsInstance(error, facemorph.Error)
        self.assertEqual(error.status, facemorph._decoder.status_name(error.code))
        for text in named:
            self.assertIn(text, str(error))
        return error

    def test_classes_follow_fm_status(self):
        names = {cls.code: cls for cls in (getattr(facemorph, n) for n in facemorph.errors.__all__) if cls is not facemorph.Error}
        self.assertEqual(sorted(names), list(range(1, 18)))
        for code, cls in names.items():
            self.assertEqual(cls.status, facemorph._decoder.status_name(code))
            self.assertTrue(issubclass(cls, facemorph.Error))
        self.assertTrue(issubclass(facemorph.InvalidArgumentError, ValueError))
        self.assertTrue(issubclass(facemorph.OutOfRangeError, ValueError))

    def test_files_at_fault(self):
        missing = os.path.join(support.WORK, "missing.fmv")
        self.expect(facemorph.IoError, lambda: facemorph.open(missing), missing)
        truncated = damaged("truncated.fmv", self.data[:len(self.data) // 2])
        self.expect(facemorph.TruncatedError, lambda: facemorph.open(truncated), truncated, "truncated")
        self.expect(facemorph.TruncatedError, lambda: facemorph.open(self.data[:len(self.data) // 2]), "memory")
        header = bytearray(self.data)
        header[self.data.find(b"HEAD") + 40] ^= 0xFF
        bad_header = damaged("bad_header.fmv", bytes(header))
        self.expect(facemorph.CorruptError, lambda: facemorph.open(bad_header), bad_header, "HEAD", "checksum")
        not_fmv = damaged("picture.png", b"\x89PNG\r\n\x1a\n" + bytes(200))
        self.expect(facemorph.CorruptError, lambda: facemorph.open(not_fmv), not_fmv, "not a facemorph")

    def test_a_damaged_keyframe_fails_its_decodes_naming_the_chunk(self):
        # Opening reads the header and index only: the keyframe group's damage shows at the first
        # decode that needs it, and at every one after.
        group = bytearray(self.data)
        group[self.data.find(b"KGOP") + 40] ^= 0xFF
        path = damaged("bad_group.fmv", bytes(group))
        with facemorph.open(path) as f:
            for _ in range(2):
                self.expect(facemorph.CorruptError, lambda: f.decode(0.1), path, "KGOP", "checksum")

    def test_limits_are_applied_and_named(self):
        self.expect(facemorph.LimitError, lambda: facemorph.open(GOLDEN, max_memory=1 << 20), GOLDEN, "max_memory_bytes")
        self.expect(facemorph.LimitError, lambda: facemorph.open(GOLDEN, max_memory="1M"), GOLDEN, "max_memory_bytes")
        self.expect(facemorph.LimitError, lambda: facemorph.open(GOLDEN, max_grid_n=32), GOLDEN, "max_grid_n")
        self.expect(facemorph.LimitError, lambda: facemorph.open(GOLDEN, max_keyframes=2), GOLDEN, "max_keyframes")
        self.expect(facemorph.LimitError, lambda: facemorph.open(GOLDEN, max_texture_size=63), GOLDEN, "max_texture_size")
        self.expect(facemorph.LimitError, lambda: facemorph.open(self.data, max_grid_n=32), "memory", "max_grid_n")
        # Exactly at the file's sizes: opens.
        facemorph.open(GOLDEN, max_grid_n=33, max_keyframes=3, max_texture_size=64).close()

    def test_a_decode_stopped_by_max_work_goes_on_to_the_same_frame(self):
        unbounded = facemorph.open(GOLDEN, max_work=0).decode(0.25)
        with facemorph.open(GOLDEN, max_work=50000) as f:
            stops = 0
            while True:
                try:
                    frame = f.decode(0.25)
                    break
                except facemorph.LimitError as e:
                    self.assertIn("max_work", str(e))
                    self.assertIn(GOLDEN, str(e))
                    stops += 1
                    self.assertLess(stops, 100)
            self.assertGreater(stops, 0)
            for name in facemorph.OUTPUTS:
                self.assertEqual(getattr(frame, name).tobytes(), getattr(unbounded, name).tobytes(), name)

    def test_caller_faults(self):
        self.expect(facemorph.InvalidArgumentError, lambda: facemorph.open(GOLDEN, max_grid_n=2), "largest grid")
        self.expect(facemorph.InvalidArgumentError, lambda: facemorph.open(GOLDEN, max_memory=0), "memory")
        self.expect(facemorph.InvalidArgumentError, lambda: facemorph.open(GOLDEN, max_memory="lots"), "max_memory")
        self.expect(facemorph.InvalidArgumentError, lambda: facemorph.open(42))
        self.expect(facemorph.InvalidArgumentError, lambda: facemorph.open(GOLDEN, max_work=-1), "max_work")
        self.expect(facemorph.InvalidArgumentError, lambda: facemorph.open(GOLDEN, max_grid_n=1 << 32), "max_grid_n")
        with facemorph.open(GOLDEN) as f:
            self.expect(facemorph.InvalidArgumentError, lambda: f.decode(math.nan), "not finite")
            error = self.expect(facemorph.OutOfRangeError, lambda: f.decode(1e6), "outside the range")
            self.assertIsInstance(error, ValueError)
            self.expect(facemorph.OutOfRangeError, lambda: f.texture_weights(1e6))

    def test_closed_files(self):
        f = facemorph.open(GOLDEN)
        f.close()
        f.close()  # twice: nothing
        self.assertTrue(f.closed)
        self.expect(facemorph.ClosedHandleError, lambda: f.decode(0.1), GOLDEN, "closed")
        self.expect(facemorph.ClosedHandleError, lambda: f.texture_weights(0.1), GOLDEN)
        self.expect(facemorph.ClosedHandleError, lambda: f.keyframe_texture(0), GOLDEN)
        self.assertEqual(f.info["keyframe_count"], 3)  # what was read stays readable
        with facemorph.open(GOLDEN) as g:
            pass
        self.expect(facemorph.ClosedHandleError, lambda: g.decode(0.1))


if __name__ == "__main__":
    support.main()
