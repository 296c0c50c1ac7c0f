"""Python.ImportLoadsNoEncoder: `import facemorph` and decoding load the decoder's module alone: not
the encoder's, not OpenCV (what a player, or Blender, pays for); encode loads them when called."""

import importlib
import sys
import unittest

import support
import facemorph


def mapped_libraries():
    with open("/proc/self/maps") as f:
        return {line.split()[-1] for line in f if "/" in line}


class ImportLoadsNoEncoder(unittest.TestCase):
    def test_decoding_loads_no_opencv(self):
        with facemorph.open(support.GOLDEN[1]) as f:
            f.decode(0.2)
            f.keyframe_texture(0)
        self.assertNotIn("facemorph._encoder", sys.modules)
        opencv = [path for path in mapped_libraries() if "libopencv" in path]
        self.assertEqual(opencv, [])
        try:
            importlib.import_module("facemorph._encoder")
        except ImportError:
            self.skipTest("no encoder module in this build (FACEMORPH_BUILD_ENCODER=OFF)")
        self.assertTrue(any("libopencv" in path for path in mapped_libraries()))


if __name__ == "__main__":
    support.main()
