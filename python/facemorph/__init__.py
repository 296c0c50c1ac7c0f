"""facemorph: compressed 3D facial video for Python and numpy.

Decode any time t of a ``.fmv`` file into numpy arrays, and encode a capture (a folder, or frames as
numpy arrays) into one::

    import facemorph
    with facemorph.open("face.fmv") as f:
        print(f.info["range"], f.info["keyframe_count"], f.info["grid_n"])
        frame = f.decode(1.45)
        frame.positions, frame.normals, frame.uv, frame.faces, frame.texture   # numpy arrays

    facemorph.encode("capture/", "face.fmv", keyframes="10%")
    facemorph.encode([{"vertices": v, "faces": tri, "uv": uv, "texture": img} for v in meshes],
                     "face.fmv", fps=30)

Decoding uses the player C API (facemorph.h) and never loads the encoder; :func:`encode` loads the
encoder's module (OpenCV) on first use. Failures raise :class:`Error` subclasses named after the C
API's statuses (:class:`CorruptError`, :class:`LimitError`, ...) with the library's message.
``python3 -m facemorph info|decode|encode`` does what fminfo, fmdec and fmenc do, in brief.
See spec/python.md.
"""

from . import _decoder
from .decode import OUTPUTS, File, Frame, open
from .encode import encode, read_image, read_mesh
from .errors import *  # noqa: F401,F403 (the exception classes)
from .errors import __all__ as _error_names

__version__: str = _decoder.version()
"""The library's version (fm_version)."""

DEFAULT_MAX_MEMORY: int = _decoder.DEFAULT_MAX_MEMORY
DEFAULT_MAX_WORK: int = _decoder.DEFAULT_MAX_WORK

__all__ = ["open", "File", "Frame", "OUTPUTS", "encode", "read_mesh", "read_image", "DEFAULT_MAX_MEMORY",
           "DEFAULT_MAX_WORK"] + list(_error_names)
