"""Decoding: :func:`open` a ``.fmv`` file, read its :attr:`File.info`, :meth:`File.decode` any time t.

Everything goes through the player C API (``facemorph.h``), so Python gets exactly what a player
gets: the same limits, the same frames bit for bit, the same errors.
"""

from __future__ import annotations

import json
import os
from typing import Any, Dict, Iterable, Optional, Tuple, Union

import numpy as np

from . import _decoder
from .errors import InvalidArgumentError

__all__ = ["open", "File", "Frame", "OUTPUTS", "parse_bytes"]

Frame = _decoder.Frame
"""One decoded frame (returned by :meth:`File.decode`). Attributes:

- ``time``: the time decoded, seconds (t, or t clamped).
- ``positions``: float32 array (n, 3), in the capture's units (``info["units"]``).
- ``normals``: float32 array (n, 3), unit, area-weighted.
- ``uv``: float32 array (n, 2), v up (OpenGL, OBJ) unless decoded with ``flip_v``.
- ``faces``: int32 array (m, 3), counter-clockwise seen from the side the normals point to.
- ``texture``: uint8 array (M, M, 3), RGB, row 0 at the top (v = 1); None without texture.
- ``vertex_count``, ``triangle_count``, ``texture_size``, ``iterations``; ``fell_back``: True
  where the reconstruction did not converge and the frame is the keyframes' blended surface.

An output not asked for (``outputs``) is None. Each array is a new one, owned by Python.
"""

OUTPUTS = ("positions", "normals", "uv", "faces", "texture")
"""What :meth:`File.decode` can give; it gives all of them unless told ``outputs=``."""

_OUTPUT_BITS = {
    "positions": _decoder.OUTPUT_POSITIONS,
    "normals": _decoder.OUTPUT_NORMALS,
    "uv": _decoder.OUTPUT_UV,
    "faces": _decoder.OUTPUT_FACES,
    "texture": _decoder.OUTPUT_TEXTURE,
}

PathOrBytes = Union[str, "os.PathLike[str]", bytes, bytearray, memoryview]


def parse_bytes(value: Union[int, str, None], what: str) -> Optional[int]:
    """A byte count given as an int or as text with a binary suffix (``"64M"``, ``"1G"``, ``"512k"``)."""
    if value is None or isinstance(value, int) and not isinstance(value, bool):
        return value
    if isinstance(value, str):
        text = value.strip()
        scale = {"k": 1 << 10, "m": 1 << 20, "g": 1 << 30}.get(text[-1:].lower(), 1)
        number = text[:-1] if scale != 1 else text
        try:
            return int(float(number) * scale)
        except ValueError:
            pass
    raise InvalidArgumentError(f"{what} {value!r} is not a byte count (an int, or text such as 64M or 1G)")


def _limit(value: Optional[int], what: str, bits: int) -> Optional[int]:
    """A limit as fm_decoder_options holds it (None: the default), or InvalidArgumentError."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value < (1 << bits):
        raise InvalidArgumentError(f"{what} {value!r} is not a whole number in 0..2^{bits}-1")
    return int(value)


def _flags(clamp: bool, keep_holes_filled: bool, flip_v: bool) -> int:
    return ((_decoder.DECODE_CLAMP if clamp else 0) | (_decoder.DECODE_KEEP_HOLES_FILLED if keep_holes_filled else 0)
            | (_decoder.DECODE_FLIP_V if flip_v else 0))


class File:
    """An opened ``.fmv`` file and its decoder. Make one with :func:`facemorph.open`.

    A file is closed by :meth:`close`, by leaving a ``with`` block, or when it is collected. One
    call at a time decodes on a File (calls from several threads wait for each other); open the
    file once per thread to decode in parallel. The GIL is released while decoding.
    """

    def __init__(self, source: PathOrBytes, *, max_memory: Union[int, str, None] = None, max_work: Optional[int] = None,
                 max_grid_n: Optional[int] = None, max_keyframes: Optional[int] = None,
                 max_texture_size: Optional[int] = None) -> None:
        limits = _decoder.Limits(max_memory=_limit(parse_bytes(max_memory, "max_memory"), "max_memory", 64), max_work=_limit(max_work, "max_work", 64),
                                 max_grid_n=_limit(max_grid_n, "max_grid_n", 32), max_keyframes=_limit(max_keyframes, "max_keyframes", 32),
                                 max_texture_size=_limit(max_texture_size, "max_texture_size", 32))
        if isinstance(source, (bytes, bytearray, memoryview)):
            # Kept as an immutable bytes object that the C API reads where it lies.
            self._file = _decoder.File.open_bytes(bytes(source), limits)
        elif isinstance(source, (str, os.PathLike)):
            self._file = _decoder.File.open_path(os.fsdecode(os.fspath(source)), limits)
        else:
            raise InvalidArgumentError(f"facemorph.open: a path or bytes, not {type(source).__name__}")
        self._info = _complete_info(self._file.info())

    @property
    def name(self) -> str:
        """The path the file was opened from, or ``"memory"`` (as the library's messages name it)."""
        return self._file.name

    @property
    def info(self) -> Dict[str, Any]:
        """What the file holds (a new dict each time):

        - ``fps``, ``first_time``, ``last_time``, ``duration`` (seconds): the capture's.
        - ``range``: (begin, end), the times :meth:`decode` serves without ``clamp`` (±inf with one keyframe).
        - ``keyframe_count``, ``keyframe_times`` (list of seconds).
        - ``grid_n`` (N of the disk grid), ``grid_vertex_count``, ``grid_triangle_count``,
          ``max_vertex_count``, ``max_triangle_count``, ``has_holes`` (counts change per frame).
        - ``texture_size`` (M; 0: no texture), ``texture_codec`` (``"avif"``, ``"webp"``; None).
        - ``units`` (``"m"``, ``"cm"``, ``"mm"``), ``landmark_names``, ``encoder``,
          ``format_version`` (``"2.1"``), ``file_bytes``, ``distinct_textures``.
        - ``settings``: the encoder's settings as a dict (``{}`` if the header's text is not a JSON
          object; the text itself is ``settings_text``).
        """
        info = dict(self._info)
        info["keyframe_times"] = list(info["keyframe_times"])
        info["settings"] = json.loads(info["settings_text"]) if info["settings"] else {}
        return info

    @property
    def keyframe_times(self) -> np.ndarray:
        """The keyframes' times, seconds, increasing (float64)."""
        return np.array(self._info["keyframe_times"], dtype=np.float64)

    @property
    def range(self) -> Tuple[float, float]:
        """(begin, end): the times :meth:`decode` serves without ``clamp``."""
        return self._info["range"]

    def decode(self, t: float, *, clamp: bool = False, keep_holes_filled: bool = False, flip_v: bool = False,
               outputs: Optional[Iterable[str]] = None) -> Frame:
        """The frame at time ``t`` (seconds from the capture's first frame): a :data:`Frame`.

        ``clamp``: a t outside :attr:`range` is clamped instead of raising :class:`OutOfRangeError`.
        ``keep_holes_filled``: eyes and mouth stay filled (every frame has the grid's topology).
        ``flip_v``: v down (glTF, Direct3D). ``outputs``: which of :data:`OUTPUTS` to make (all by
        default); the others are None. Raises :class:`facemorph.Error` subclasses:
        ``OutOfRangeError``, ``CorruptError`` (a keyframe that does not decode), ``LimitError``
        (``max_work``: call again to go on; ``max_memory``), ``ClosedHandleError``, ...
        """
        if outputs is None:
            bits = _decoder.OUTPUT_POSITIONS | _decoder.OUTPUT_NORMALS | _decoder.OUTPUT_UV | _decoder.OUTPUT_FACES | _decoder.OUTPUT_TEXTURE
        else:
            if isinstance(outputs, str):
                outputs = (outputs,)
            bits = 0
            for name in outputs:
                if name not in _OUTPUT_BITS:
                    raise InvalidArgumentError(f"decode: unknown output {name!r} (one of {', '.join(OUTPUTS)})")
                bits |= _OUTPUT_BITS[name]
        return self._file.decode(float(t), _flags(clamp, keep_holes_filled, flip_v), bits)

    def texture_weights(self, t: float, *, clamp: bool = False, keep_holes_filled: bool = False,
                        flip_v: bool = False) -> Tuple[np.ndarray, np.ndarray]:
        """The texture blend at t without the texture: (keyframes int64, weights float64).

        The decoded texture is, per texel and channel, ``trunc(clip(sum(float32(w_i) *
        keyframe_texture(k_i)) + 0.5, 0, 255))``, summed in float32 in this order. Weights may be 0
        or negative and sum to 1; a keyframe may appear twice (format 2.2's shared textures).
        """
        return self._file.texture_weights(float(t), _flags(clamp, keep_holes_filled, flip_v))

    def keyframe_texture(self, k: int) -> np.ndarray:
        """Keyframe ``k``'s texture as stored (the one it shows, where keyframes share one):
        uint8 (M, M, 3), RGB, row 0 at the top. ``InvalidArgumentError`` without texture or for a
        k outside ``0 .. keyframe_count - 1``; ``CorruptError`` where its chunk does not decode."""
        return self._file.keyframe_texture(int(k))

    def close(self) -> None:
        """Closes the decoder and the file (waiting for a decode in progress on another thread).
        Later calls raise :class:`ClosedHandleError`; closing twice does nothing."""
        self._file.close()

    @property
    def closed(self) -> bool:
        return self._file.closed

    def __enter__(self) -> "File":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        if self.closed:
            return f"<facemorph.File {self.name!r} closed>"
        i = self._info
        return (f"<facemorph.File {self.name!r}: {i['range'][0]:.3f}..{i['range'][1]:.3f} s, {i['keyframe_count']} keyframes, "
                f"N = {i['grid_n']}, texture {i['texture_size']}>")


def _complete_info(raw: Dict[str, Any]) -> Dict[str, Any]:
    # Whether the settings' text parses to a JSON object, settled once (a hostile header may hold
    # nesting deep enough to exhaust the parser's recursion: not a dict, then).
    try:
        settings = json.loads(raw["settings_text"]) if raw["settings_text"] else None
    except (ValueError, RecursionError):
        settings = None
    raw["settings"] = isinstance(settings, dict)
    raw["keyframe_times"] = tuple(raw["keyframe_times"])
    return raw


def open(source: PathOrBytes, *, max_memory: Union[int, str, None] = None, max_work: Optional[int] = None,
         max_grid_n: Optional[int] = None, max_keyframes: Optional[int] = None, max_texture_size: Optional[int] = None) -> File:
    """Opens a ``.fmv`` file: a path (str or os.PathLike) or its bytes (bytes, bytearray, memoryview).

    Only the header and index are read; keyframes are decoded when a frame first needs them. The
    limits are the C API's ``fm_decoder_options`` (None: its default; spec/container.md §10):
    ``max_memory`` bytes (an int or ``"64M"``; default 256 MiB) an opened file and its decoder may
    hold, ``max_work`` units one decode may do (default 16,000,000, about a second; 0: no bound),
    ``max_grid_n`` (1025), ``max_keyframes`` (65536), ``max_texture_size`` (4096). Raises
    :class:`IoError`, :class:`TruncatedError`, :class:`CorruptError`, :class:`UnsupportedError`,
    :class:`LimitError` (naming the limit), :class:`InvalidArgumentError` (limits that cannot work).
    """
    return File(source, max_memory=max_memory, max_work=max_work, max_grid_n=max_grid_n, max_keyframes=max_keyframes,
                max_texture_size=max_texture_size)
