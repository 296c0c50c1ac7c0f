"""Python.NoLeakOver1000Opens: opening, decoding and closing a file 1000 times (by path and from
bytes, closed by close(), by `with` and by the garbage collector) leaves the process's memory where
it was: resident set within 4 MiB, Python's own allocations (tracemalloc) within 256 kB.

One decoder on the golden file holds about 1.6 MiB (its grid, solver, keyframes and textures), so a
File whose decoder or file is never closed shows as hundreds of MiB over 1000 opens."""

import gc
import os
import tracemalloc
import unittest

import support
import facemorph


def rss_bytes():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


class NoLeak(unittest.TestCase):
    def test_1000_opens(self):
        path = support.GOLDEN[1]
        with open(path, "rb") as f:
            data = f.read()

        def cycle(i):
            way = i % 3
            if way == 0:
                f = facemorph.open(path)
                frame = f.decode(0.1 + 0.0001 * (i % 7))
                f.close()
            elif way == 1:
                with facemorph.open(data) as f:
                    frame = f.decode(0.2)
                    f.texture_weights(0.2)
            else:
                f = facemorph.open(path)  # left to the collector
                frame = f.decode(0.3)
                f.keyframe_texture(1)
                del f
            assert frame.positions.shape[0] > 0
            try:  # a failed open leaks nothing either
                facemorph.open(path, max_grid_n=8)
            except facemorph.LimitError:
                pass

        for i in range(60):  # the allocator's and the caches' steady state
            cycle(i)
        gc.collect()
        tracemalloc.start()
        before_rss = rss_bytes()
        before_py, _ = tracemalloc.get_traced_memory()
        for i in range(1000):
            cycle(i)
        gc.collect()
        after_py, _ = tracemalloc.get_traced_memory()
        after_rss = rss_bytes()
        tracemalloc.stop()
        print(f"RSS {before_rss / 2**20:.1f} -> {after_rss / 2**20:.1f} MiB; Python heap {before_py / 1024:.0f} -> {after_py / 1024:.0f} kB")
        self.assertLess(after_rss - before_rss, 4 << 20)
        self.assertLess(after_py - before_py, 256 << 10)


if __name__ == "__main__":
    support.main()
