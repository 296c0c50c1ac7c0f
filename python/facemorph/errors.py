"""The exceptions facemorph raises: one class per status of the C API (``fm_status``).

Every failure is a :class:`Error`; its subclass says which status the library returned, and its
message is the library's own (``fm_last_error_message``), naming the file, the chunk or frame and the
reason. ``status`` is the status's stable short name (``fm_status_name``: ``"corrupt"``,
``"limit"``, ...) and ``code`` its number, which never changes.

    try:
        f = facemorph.open("face.fmv", max_memory=64 << 20)
    except facemorph.LimitError as e:      # the file needs more than max_memory allows
        print(e)                           # "face.fmv: ... max_memory_bytes ..."
    except facemorph.Error as e:           # any other failure
        print(e.status, e)
"""

from __future__ import annotations

__all__ = [
    "Error", "IoError", "ParseError", "TruncatedError", "CorruptError", "UnsupportedError",
    "InvalidMeshError", "NotADiskError", "MissingTextureError", "InvalidArgumentError",
    "NumericalError", "NotConvergedError", "OutOfRangeError", "BufferTooSmallError",
    "OutOfMemoryError", "InternalError", "LimitError", "ClosedHandleError",
]


class Error(Exception):
    """A failure facemorph reports. ``str(e)`` is the library's message."""

    code: int = -1
    """The ``fm_status`` value (stable: never renumbered)."""
    status: str = "unknown"
    """The status's short name, as ``fm_status_name`` gives it."""

    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.message = message


class IoError(Error):
    """FM_ERROR_IO: a file could not be opened, read or written."""
    code, status = 1, "io"


class ParseError(Error):
    """FM_ERROR_PARSE: text or structure that does not follow its grammar."""
    code, status = 2, "parse"


class TruncatedError(Error):
    """FM_ERROR_TRUNCATED: the input ends before the data it announces."""
    code, status = 3, "truncated"


class CorruptError(Error):
    """FM_ERROR_CORRUPT: bytes present but wrong (a checksum, an impossible value)."""
    code, status = 4, "corrupt"


class UnsupportedError(Error):
    """FM_ERROR_UNSUPPORTED: a valid input using a feature this build does not implement."""
    code, status = 5, "unsupported"


class InvalidMeshError(Error):
    """FM_ERROR_INVALID_MESH: a frame with non-finite coordinates, bad indices, non-manifold edges."""
    code, status = 6, "invalid-mesh"


class NotADiskError(Error):
    """FM_ERROR_NOT_A_DISK: a frame that cannot be made one open surface with one boundary."""
    code, status = 7, "not-a-disk"


class MissingTextureError(Error):
    """FM_ERROR_MISSING_TEXTURE: a texture image that does not exist or cannot be decoded."""
    code, status = 8, "missing-texture"


class InvalidArgumentError(Error, ValueError):
    """FM_ERROR_INVALID_ARGUMENT: the caller's fault, never the file's (also a ValueError)."""
    code, status = 9, "invalid-argument"


class NumericalError(Error):
    """FM_ERROR_NUMERICAL: the reconstruction failed numerically (a corrupt file)."""
    code, status = 10, "numerical"


class NotConvergedError(Error):
    """FM_ERROR_NOT_CONVERGED: an iteration stopped before meeting its tolerance."""
    code, status = 11, "not-converged"


class OutOfRangeError(Error, ValueError):
    """FM_ERROR_OUT_OF_RANGE: t outside the file's range without ``clamp`` (also a ValueError)."""
    code, status = 12, "out-of-range"


class BufferTooSmallError(Error):
    """FM_ERROR_BUFFER_TOO_SMALL: an output buffer too small (never raised by this package)."""
    code, status = 13, "buffer-too-small"


class OutOfMemoryError(Error):
    """FM_ERROR_OUT_OF_MEMORY: an allocation failed."""
    code, status = 14, "out-of-memory"


class InternalError(Error):
    """FM_ERROR_INTERNAL: a bug in facemorph; please report it with the message."""
    code, status = 15, "internal"


class LimitError(Error):
    """FM_ERROR_LIMIT: the file needs more than the decoder's limits allow.

    The message names the limit (``max_memory_bytes``, ``max_work``, ``max_grid_n``, ...). A decode
    stopped by ``max_work`` keeps what it finished: calling ``decode`` again at the same t goes on
    from there, to the same frame one unbounded call makes.
    """
    code, status = 16, "limit"


class ClosedHandleError(Error):
    """FM_ERROR_CLOSED_HANDLE: a file used after ``close()``."""
    code, status = 17, "closed-handle"


_BY_CODE = {cls.code: cls for cls in (
    IoError, ParseError, TruncatedError, CorruptError, UnsupportedError, InvalidMeshError,
    NotADiskError, MissingTextureError, InvalidArgumentError, NumericalError, NotConvergedError,
    OutOfRangeError, BufferTooSmallError, OutOfMemoryError, InternalError, LimitError,
    ClosedHandleError)}


def _from_status(code: int, message: str) -> Error:
    """The exception for a status (the extension modules raise through this)."""
    return _BY_CODE.get(code, Error)(message)
