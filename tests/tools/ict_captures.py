#!/usr/bin/env python3
"""Writes several stretches of ICT speech as facemorph captures in one process, with the data's own
script (../shared/data/ict-facekit/tools/make_capture.py). Each run of that script reads the ICT
model's 53 compressed shapes again, about 34 CPU-seconds, for a capture of one to three frames: the
real-data tests that each ran it spent most of their time there. Here the shapes are read once, and
for their positions only, and every stretch is made from them, byte for byte what the script writes
alone.

usage: ict_captures.py ICT_TOOLS_DIR OUT_DIR START,SECONDS,FPS ...
   OUT_DIR/ict_START_SECONDS_FPS/ per stretch (the name tests/test_util.hpp's ict_speech_capture looks for),
   written under a temporary name and renamed. Writes nothing, and succeeds, where the data is absent.
"""
import functools, os, shutil, sys


def main():
    tools, out, stretches = sys.argv[1], sys.argv[2], sys.argv[3:]
    if not os.path.isfile(os.path.join(tools, 'make_capture.py')):
        print('ict_captures: no ICT data at', tools, '(the tests make their own or skip)')
        return 0
    sys.path.insert(0, tools)
    import ict_face_sequence, make_capture
    read_whole_obj = ict_face_sequence.read_obj_xz

    # The animation reads a shape only for its positions (read_obj_xz(shape)[0]); the neutral mesh
    # is read whole (its UVs and polygons are the capture's). Parsing a shape's 28,911 UVs and 26,384
    # polygons as well was most of the 34 CPU-seconds: its positions alone, parsed by the script's
    # own expression, are the same floats.
    def read_obj_xz(name):
        if name == 'generic_neutral_mesh':
            return read_whole_obj(name)
        with ict_face_sequence.lzma.open(os.path.join(ict_face_sequence.SRC, name + '.obj.xz'), 'rt') as f:
            return [[float(x) for x in line.split()[1:4]] for line in f if line.startswith('v ')], None, None
    ict_face_sequence.read_obj_xz = functools.lru_cache(maxsize=None)(read_obj_xz)

    def run_in_process(command, check):  # make_capture runs ict_face_sequence.py as a program
        sys.argv = command[1:]
        ict_face_sequence.main()
    make_capture.subprocess.run = run_in_process
    os.makedirs(out, exist_ok=True)
    for stretch in stretches:
        start, seconds, fps = stretch.split(',')
        name = os.path.join(out, 'ict_%s_%s_%s' % (start, seconds, fps))
        if os.path.isfile(os.path.join(name, 'capture.json')):
            continue
        partial = name + '.partial'
        shutil.rmtree(partial, ignore_errors=True)
        sys.argv = ['make_capture.py', partial, '--start-seconds', start, '--seconds', seconds, '--fps', fps]
        make_capture.main()
        os.rename(partial, name)
    return 0


if __name__ == '__main__':
    sys.exit(main())
