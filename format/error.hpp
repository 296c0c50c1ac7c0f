// facemorph error reporting.
//
// Every failure facemorph reports is a facemorph::Error: a stable, named code plus a message that
// names the file / frame / field and the reason. Library code throws; tools and the C API catch at
// their boundary, print the message on stderr and return a non-zero status.
#pragma once

#include <stdexcept>
#include <string>

namespace facemorph {

// Every code once, the one list the rest is made from: its enumerator, its value, its short stable
// name and the C API's name for it (facemorph.h's fm_status, which must keep the same value:
// codec/decoder/player/c_api.cpp checks every row against the header and maps codes to statuses
// from this list). Values are part of the C API and never renumbered; new codes are appended.
#define FACEMORPH_ERROR_CODES(X)                                                                                                          \
  X(kOk, 0, "ok", FM_OK)                                                                                                                  \
  X(kIo, 1, "io", FM_ERROR_IO)                              /* a file could not be opened, read or written */                             \
  X(kParse, 2, "parse", FM_ERROR_PARSE)                     /* text or structure that does not follow its grammar */                      \
  X(kTruncated, 3, "truncated", FM_ERROR_TRUNCATED)         /* the input ends before the data it announces ("not enough bytes") */        \
  X(kCorrupt, 4, "corrupt", FM_ERROR_CORRUPT)               /* bytes are present but wrong (checksum, impossible value) */                \
  X(kUnsupported, 5, "unsupported", FM_ERROR_UNSUPPORTED)   /* a valid input using a feature facemorph does not implement */              \
  X(kInvalidMesh, 6, "invalid-mesh", FM_ERROR_INVALID_MESH) /* NaN/Inf, out-of-range index, non-manifold, non-orientable */               \
  X(kNotADisk, 7, "not-a-disk", FM_ERROR_NOT_A_DISK)        /* a frame that cannot be made one open surface with one boundary */          \
  X(kMissingTexture, 8, "missing-texture", FM_ERROR_MISSING_TEXTURE)    /* a referenced texture image is missing or undecodable */        \
  X(kInvalidArgument, 9, "invalid-argument", FM_ERROR_INVALID_ARGUMENT) /* a caller-supplied option or value outside its domain */        \
  X(kNumerical, 10, "numerical", FM_ERROR_NUMERICAL)                    /* a numerical method failed (singular system, NaN produced) */   \
  X(kNotConverged, 11, "not-converged", FM_ERROR_NOT_CONVERGED)         /* an iteration stopped before meeting its tolerance */           \
  X(kOutOfRange, 12, "out-of-range", FM_ERROR_OUT_OF_RANGE)             /* a request outside what the data can serve (t too far out) */   \
  X(kBufferTooSmall, 13, "buffer-too-small", FM_ERROR_BUFFER_TOO_SMALL) /* a caller's buffer smaller than the data */                     \
  X(kOutOfMemory, 14, "out-of-memory", FM_ERROR_OUT_OF_MEMORY)          /* an allocation failed */                                        \
  X(kInternal, 15, "internal", FM_ERROR_INTERNAL)                       /* none of the above (a bug in facemorph: please report it) */    \
  X(kLimit, 16, "limit", FM_ERROR_LIMIT)                                /* an input needing more than the caller's DecoderLimits allow */ \
  X(kClosedHandle, 17, "closed-handle", FM_ERROR_CLOSED_HANDLE)         /* a C API handle used after it was closed (or closed twice) */

enum class ErrorCode : int {
#define FACEMORPH_ERROR_ENUMERATOR(code, value, name, status) code = value,
  FACEMORPH_ERROR_CODES(FACEMORPH_ERROR_ENUMERATOR)
#undef FACEMORPH_ERROR_ENUMERATOR
};

// How many codes there are (values 0 .. kErrorCodeCount - 1, none skipped: checked in c_api.cpp).
#define FACEMORPH_ERROR_COUNT_ONE(code, value, name, status) +1
inline constexpr int kErrorCodeCount = 0 FACEMORPH_ERROR_CODES(FACEMORPH_ERROR_COUNT_ONE);
#undef FACEMORPH_ERROR_COUNT_ONE

// Short stable name of a code, e.g. "truncated"; never null.
constexpr const char* error_code_name(ErrorCode code) noexcept {
  switch (code) {
#define FACEMORPH_ERROR_NAME_CASE(code, value, name, status) \
  case ErrorCode::code: return name;
    FACEMORPH_ERROR_CODES(FACEMORPH_ERROR_NAME_CASE)
#undef FACEMORPH_ERROR_NAME_CASE
  }
  return "unknown";
}

class Error : public std::runtime_error {
 public:
  Error(ErrorCode code, const std::string& message) : std::runtime_error(message), code_(code) {}
  ErrorCode code() const noexcept { return code_; }

 private:
  ErrorCode code_;
};

}  // namespace facemorph
