"""Encoding: :func:`encode` a capture folder, or frames given as numpy arrays, into a ``.fmv`` file.

Through the encoder's C++ library (module ``facemorph._encoder``, which links OpenCV; it is loaded
on the first call, so ``import facemorph`` and decoding never load it). The same frames and options
make the same bytes as ``fmenc``.
"""

from __future__ import annotations

import math
import os
from typing import Any, Callable, Dict, Iterable, List, Mapping, Optional, Sequence, Union

import numpy as np

from .errors import InvalidArgumentError

__all__ = ["encode", "read_mesh", "read_image"]

ProgressCallback = Callable[[str, int, int], Any]


def _encoder():
    try:
        from . import _encoder as module
    except ImportError as e:
        from .errors import UnsupportedError
        raise UnsupportedError(f"facemorph.encode: this build has no encoder module (facemorph._encoder: {e}); "
                               "build with FACEMORPH_BUILD_ENCODER=ON (needs OpenCV)") from None
    return module


def _fraction(value: Union[float, str, None], what: str) -> Optional[float]:
    """10%, "10%" or 0.1 -> 0.1 (fmenc's fractions); None stays None."""
    if value is None:
        return None
    number: float
    try:
        if isinstance(value, str):
            text = value.strip()
            number = float(text[:-1]) / 100 if text.endswith("%") else float(text)
        else:
            number = float(value)
    except ValueError:
        raise InvalidArgumentError(f"{what} {value!r} is not a fraction in (0, 1] (e.g. '10%' or 0.1)") from None
    if not (0 < number <= 1):
        raise InvalidArgumentError(f"{what} {value!r} is not a fraction in (0, 1] (e.g. '10%' or 0.1)")
    return number


def _auto_int(value: Union[int, str, None], what: str) -> Optional[int]:
    if value is None or value == "auto":
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InvalidArgumentError(f"{what} {value!r} is neither 'auto' nor a whole number")
    return int(value)


def read_mesh(path: Union[str, "os.PathLike[str]"]) -> Dict[str, Any]:
    """A mesh file (OBJ, PLY) as numpy arrays, as the encoder reads it: ``vertices`` (n, 3) float64,
    ``faces`` (m, 3) int32, ``uv`` (k, 2) float64 and ``uv_faces`` (m, 3) int32 (or None),
    ``colours`` (n, 3) float64 in [0, 1] (or None), ``texture_path`` (or None). Raises
    :class:`IoError`, :class:`ParseError`, :class:`TruncatedError`, :class:`InvalidMeshError`."""
    return _encoder().read_mesh(os.fsdecode(os.fspath(path)))


def read_image(path: Union[str, "os.PathLike[str]"]) -> np.ndarray:
    """An image file (PNG, JPEG, WebP) as uint8 (H, W, 3) RGB, row 0 at the top.
    Raises :class:`MissingTextureError` naming the file."""
    return _encoder().read_image(os.fsdecode(os.fspath(path)))


def _get(frame: Any, *names: str) -> Any:
    for name in names:
        if isinstance(frame, Mapping):
            if name in frame and frame[name] is not None:
                return frame[name]
        elif getattr(frame, name, None) is not None:
            return getattr(frame, name)
    return None


def _array(value: Any, dtype: Any, columns: int, what: str) -> np.ndarray:
    array = np.asarray(value)
    if array.ndim != 2 or array.shape[1] != columns:
        raise InvalidArgumentError(f"{what}: an array of shape (count, {columns}), not {array.shape}")
    if np.issubdtype(dtype, np.integer):
        if not np.issubdtype(array.dtype, np.integer):
            raise InvalidArgumentError(f"{what}: integers, not {array.dtype}")
        if array.size and (array.min() < 0 or array.max() > np.iinfo(np.int32).max):
            raise InvalidArgumentError(f"{what}: indices outside 0..2^31-1")
    return np.ascontiguousarray(array, dtype=dtype)


def _frames_to_native(frames: Sequence[Any], fps: Optional[float], times: Optional[Sequence[float]], names: Optional[Sequence[str]],
                      landmarks: Optional[Mapping[str, Any]]):
    module = _encoder()
    if len(frames) == 0:
        raise InvalidArgumentError("facemorph.encode: no frames")
    native: List[Any] = []
    textures: List[np.ndarray] = []
    texture_index: Dict[int, int] = {}  # id() of a texture array given -> its index: one array, one image file
    held: List[Any] = []  # keeps the arrays whose id() is a key alive
    frame_times: List[float] = []
    frame_landmarks: List[Mapping[str, Any]] = []
    for i, frame in enumerate(frames):
        what = f"frame {i}"
        vertices = _get(frame, "vertices", "positions")
        faces = _get(frame, "faces")
        if vertices is None or faces is None:
            raise InvalidArgumentError(f"{what}: needs vertices (n, 3) and faces (m, 3)")
        vertices = _array(vertices, np.float64, 3, f"{what} vertices")
        faces = _array(faces, np.int32, 3, f"{what} faces")
        if faces.size and faces.max() >= len(vertices):
            raise InvalidArgumentError(f"{what} faces: index {int(faces.max())} for {len(vertices)} vertices")
        uv = _get(frame, "uv", "uvs")
        uv_faces = _get(frame, "uv_faces")
        if uv is not None:
            uv = _array(uv, np.float64, 2, f"{what} uv")
            if uv_faces is None:
                if len(uv) != len(vertices):
                    raise InvalidArgumentError(f"{what} uv: one per vertex ({len(vertices)}), or give uv_faces, not {len(uv)}")
            else:
                uv_faces = _array(uv_faces, np.int32, 3, f"{what} uv_faces")
                if len(uv_faces) != len(faces):
                    raise InvalidArgumentError(f"{what} uv_faces: one per face ({len(faces)}), not {len(uv_faces)}")
                if uv_faces.size and uv_faces.max() >= len(uv):
                    raise InvalidArgumentError(f"{what} uv_faces: index {int(uv_faces.max())} for {len(uv)} uvs")
        elif uv_faces is not None:
            raise InvalidArgumentError(f"{what}: uv_faces without uv")
        colours = _get(frame, "colours", "colors", "vertex_colors")
        if colours is not None:
            raw = np.asarray(colours)
            if raw.ndim == 2 and raw.shape[1] == 4:
                raw = raw[:, :3]  # alpha, ignored as the mesh readers ignore it
            if np.issubdtype(raw.dtype, np.integer):
                if raw.size and (raw.min() < 0 or raw.max() > 255):
                    raise InvalidArgumentError(f"{what} colours: integers in 0..255")
                # As the PLY reader scales uchar colours.
                raw = raw.astype(np.float64) * (1.0 / 255)
            colours = _array(raw, np.float64, 3, f"{what} colours")
            if len(colours) != len(vertices):
                raise InvalidArgumentError(f"{what} colours: one per vertex ({len(vertices)}), not {len(colours)}")
            if not np.all((colours >= 0) & (colours <= 1)):
                raise InvalidArgumentError(f"{what} colours: floats in [0, 1] (or uint8)")
        texture = _get(frame, "texture", "image")
        index = -1
        if texture is not None:
            if uv is None:
                raise InvalidArgumentError(f"{what}: a texture needs uv")
            index = texture_index.get(id(texture), -1)
            if index < 0:
                image = np.asarray(texture)
                if image.ndim != 3 or image.shape[2] not in (3, 4) or image.dtype != np.uint8:
                    raise InvalidArgumentError(f"{what} texture: uint8 (H, W, 3) RGB (or RGBA), not {image.dtype} {image.shape}")
                index = len(textures)
                textures.append(np.ascontiguousarray(image[:, :, :3]))
                texture_index[id(texture)] = index
                held.append(texture)
        native.append(module.NumpyFrame(vertices, faces, uv, uv_faces, colours, index))
        t = _get(frame, "time")
        frame_times.append(float(t) if t is not None else math.nan)
        frame_landmarks.append(_get(frame, "landmarks") or {})

    if times is not None:
        if len(times) != len(frames):
            raise InvalidArgumentError(f"times: one per frame ({len(frames)}), not {len(times)}")
        frame_times = [float(t) for t in times]
    elif any(math.isnan(t) for t in frame_times):
        if not all(math.isnan(t) for t in frame_times):
            raise InvalidArgumentError("frames: a time on every frame or on none")
        if fps is None:
            raise InvalidArgumentError("facemorph.encode: frames without times need fps")
        frame_times = [i / fps for i in range(len(frames))]
    if fps is None:
        steps = np.diff(frame_times)
        if len(steps) == 0 or not np.all(steps > 0):
            raise InvalidArgumentError("facemorph.encode: give fps (the frames' times do not say it)")
        fps = 1.0 / float(np.median(steps))

    if names is None:
        names = [f"frame_{i:04d}.obj" for i in range(len(frames))]
    else:
        names = [n if n.lower().endswith(".obj") else n + ".obj" for n in names]
        if len(names) != len(frames) or len(set(names)) != len(names) or any("/" in n or "\\" in n or n.startswith(".") for n in names):
            raise InvalidArgumentError("names: one plain file name per frame, each different")

    # Landmarks: a dict name -> (frames, 3) array, or each frame's dict name -> (x, y, z); NaN: absent.
    landmark_names: List[str] = []
    if landmarks is not None:
        landmark_names = list(landmarks.keys())
    for given in frame_landmarks:
        for name in given:
            if name not in landmark_names:
                landmark_names.append(name)
    points = np.full((len(frames), len(landmark_names), 3), np.nan)
    for j, name in enumerate(landmark_names):
        if landmarks is not None and name in landmarks:
            column = np.asarray(landmarks[name], dtype=np.float64)
            if column.shape != (len(frames), 3):
                raise InvalidArgumentError(f"landmarks[{name!r}]: shape ({len(frames)}, 3), not {column.shape}")
            points[:, j] = column
        for i, given in enumerate(frame_landmarks):
            if name in given:
                point = np.asarray(given[name], dtype=np.float64)
                if point.shape != (3,):
                    raise InvalidArgumentError(f"frame {i} landmark {name!r}: (x, y, z), not shape {point.shape}")
                points[i, j] = point
    return native, textures, frame_times, list(names), float(fps), landmark_names, points


def encode(source: Union[str, "os.PathLike[str]", Sequence[Any]], out: Union[str, "os.PathLike[str]"], *,
           fps: Optional[float] = None, times: Optional[Sequence[float]] = None, units: str = "m",
           landmarks: Union[str, "os.PathLike[str]", Mapping[str, Any], None] = None, names: Optional[Sequence[str]] = None,
           keyframes: Union[float, str, None] = None, max_error: Union[float, str, None] = None,
           grid: Union[int, str] = "auto", texture: bool = True, texture_size: Union[int, str] = "auto",
           quality: Union[int, str] = "auto", texture_codec: str = "avif", texture_coding: str = "sequence",
           texture_sharing: bool = True, registration: str = "gmf", spline: str = "catmull-rom",
           representation: str = "auto", density_equalising: float = 0.0, keyframe_fit: bool = True, reference: int = 0,
           field_error: Union[float, str] = "auto", field_rounding: str = "shaped", inter_dead_zone: Union[float, str] = "auto",
           intra_period: Union[int, str] = "auto", track_landmarks: bool = False, largest_component: bool = False,
           keep_holes_filled: bool = False, strict: bool = False, threads: int = 0,
           progress: Optional[ProgressCallback] = None) -> Dict[str, Any]:
    """Encodes a capture into the ``.fmv`` file ``out`` (written whole or not at all), as ``fmenc`` does.

    ``source`` is either

    - a capture folder with ``capture.json`` (or that file), or a plain folder of OBJ/PLY frames
      with ``fps`` and, optionally, ``landmarks`` (a CSV file ``frame,name,x,y,z``, or ``"auto"``:
      ignore the capture's landmarks and find them from the geometry); or
    - a sequence of frames, each a dict (or an object with these attributes): ``vertices`` (n, 3),
      ``faces`` (m, 3) int; optional ``uv`` ((n, 2) per vertex, or (k, 2) with ``uv_faces`` (m, 3)),
      ``texture`` (uint8 (H, W, 3) RGB, row 0 at the top; frames passing the same array share one
      image) or ``colours`` (n, 3: uint8, or float in [0, 1]), ``time`` (seconds), ``landmarks``
      (a dict name -> (x, y, z)). Times come from ``times``, else the frames, else i / ``fps``.
      ``landmarks`` may instead be a dict name -> (frames, 3) array (NaN where a frame lacks one);
      without landmarks the encoder finds the nose tip, up and rim from the geometry. ``units``:
      ``"m"``, ``"cm"`` or ``"mm"``; ``names``: the frames' names in messages (``frame_0000``...).

    Options are fmenc's (``fmenc --help``): ``keyframes`` (a budget: 0.1 or ``"10%"``; default 10%,
    growing where frames are far apart or fast), ``max_error`` (instead: the predicted error bound,
    of the bounding-box diagonal), ``grid`` (N or ``"auto"``), ``texture`` (False: geometry only),
    ``texture_size``, ``quality`` (0..100, 101 lossless WebP, ``"auto"``), ``texture_codec``
    (``"avif"``, ``"webp"``), ``texture_coding`` (``"sequence"``, ``"stills"``), ``texture_sharing``,
    ``registration`` (``"moebius"``, ``"gmf"``, ``"frame"``), ``spline``, ``representation``
    (``"auto"``, ``"hl+t"``, ``"hl"``, ``"xyz"``), ``density_equalising``, ``keyframe_fit``,
    ``reference``, ``field_error`` (``"auto"``, 0, or a fraction), ``field_rounding``,
    ``inter_dead_zone``, ``intra_period``, ``track_landmarks``, ``largest_component``,
    ``keep_holes_filled``, ``strict``, ``threads`` (0: one per core).

    ``progress(stage, done, total)`` is called as the encode goes (stages ``"mapping"``,
    ``"registering"``, ``"keyframes"``, ...); an exception it raises (or Ctrl-C) ends the encode and
    is raised. The GIL is released while encoding.

    Returns a report: ``output``, ``bytes``, ``frames`` (encoded), ``keyframe_times``,
    ``keyframe_frames``, ``grid_n``, ``representation``, ``texture_size``,
    ``predicted_worst_error``, ``dropped`` (frames left out: frame, name, time, reason),
    ``warnings``, ``settings`` (as written into the file), ``seconds``. Raises
    :class:`facemorph.Error` subclasses with the encoder's message naming the frame (in ``strict``
    mode, or when no frame is left), :class:`InvalidArgumentError` for bad options or arrays.
    """
    import json

    module = _encoder()
    if keyframes is not None and max_error is not None:
        raise InvalidArgumentError("facemorph.encode: keyframes or max_error, not both")
    if quality != "auto" and (isinstance(quality, bool) or not isinstance(quality, (int, np.integer))):
        raise InvalidArgumentError(f"quality {quality!r} is neither 'auto' nor a number 0..101")
    if field_rounding not in ("shaped", "nearest"):
        raise InvalidArgumentError(f"field_rounding {field_rounding!r} is neither shaped nor nearest")
    if field_error == "auto":
        field_error_value: Optional[float] = None
    elif field_error == 0 or field_error == "0":
        field_error_value = 0.0
    else:
        field_error_value = _fraction(field_error, "field_error")
    if inter_dead_zone == "auto":
        dead_zone: Optional[float] = None
    else:
        dead_zone = float(inter_dead_zone)
        if not (0.5 <= dead_zone < 1):
            raise InvalidArgumentError(f"inter_dead_zone {inter_dead_zone!r} is neither 'auto' nor a number in [0.5, 1)")
    period = _auto_int(intra_period, "intra_period")
    if period is not None and not (1 <= period <= 1 << 20):
        raise InvalidArgumentError(f"intra_period {intra_period!r} is neither 'auto' nor a whole number from 1 to 2^20")
    options = {
        "keyframes": _fraction(keyframes, "keyframes"),
        "max_error": _fraction(max_error, "max_error"),
        "grid": _auto_int(grid, "grid"),
        "texture": bool(texture),
        "texture_size": _auto_int(texture_size, "texture_size"),
        "quality": None if quality == "auto" else int(quality),
        "texture_codec": texture_codec,
        "texture_coding": texture_coding,
        "texture_sharing": bool(texture_sharing),
        "registration": registration,
        "spline": spline,
        "representation": None if representation == "auto" else representation,
        "density_equalising": float(density_equalising),
        "keyframe_fit": bool(keyframe_fit),
        "reference": int(reference),
        "field_error": field_error_value,
        "field_rounding": field_rounding,
        "inter_dead_zone": dead_zone,
        "intra_period": period,
        "track_landmarks": bool(track_landmarks),
        "largest_component": bool(largest_component),
        "keep_holes_filled": bool(keep_holes_filled),
        "strict": bool(strict),
        "threads": int(threads),
    }
    output = os.fsdecode(os.fspath(out))
    if isinstance(source, (str, os.PathLike)):
        path = os.fsdecode(os.fspath(source))
        if path.endswith(".fmv"):
            raise InvalidArgumentError(f"{path}: re-coding a .fmv file is fmenc's (facemorph.encode takes a capture)")
        if isinstance(landmarks, Mapping):
            raise InvalidArgumentError("landmarks: with a capture folder, a CSV file or 'auto'")
        auto = landmarks == "auto"
        csv = "" if landmarks is None or auto else os.fsdecode(os.fspath(landmarks))
        report = module.encode_capture(path, float(fps or 0), csv, auto, output, options, progress)
    else:
        if isinstance(landmarks, (str, os.PathLike)):
            raise InvalidArgumentError("landmarks: with frames, a dict name -> (frames, 3) array (or each frame's 'landmarks')")
        if units not in ("m", "cm", "mm"):
            raise InvalidArgumentError(f"units {units!r}: m, cm or mm")
        frames, textures, frame_times, frame_names, rate, landmark_names, points = _frames_to_native(
            list(source), fps, times, names, landmarks)
        report = module.encode_frames(frames, textures, frame_times, frame_names, rate, units, landmark_names, points, output,
                                      options, progress)
    report["settings"] = json.loads(report.pop("settings_text"))
    return report
