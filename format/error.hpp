// facemorph error reporting.
//
// Every failure facemorph reports is a facemorph::Error: a stable, named code plus a message that
// names the file / frame / field and the reason. Library code throws; tools and the C API catch at
// their boundary, print the message on stderr and return a non-zero status.
#pragma once

#include <stdexcept>
#include <string>

namespace facemorph {

// Stable codes: values are part of the C API and never renumbered; new codes are appended.
enum class ErrorCode : int {
  kOk = 0,
  kIo = 1,               // a file could not be opened, read or written
  kParse = 2,            // text or structure that does not follow its grammar
  kTruncated = 3,        // the input ends before the data it announces ("not enough bytes")
  kCorrupt = 4,          // bytes are present but wrong (checksum, impossible value)
  kUnsupported = 5,      // a valid input using a feature facemorph does not implement
  kInvalidMesh = 6,      // NaN/Inf, out-of-range index, non-manifold, non-orientable
  kNotADisk = 7,         // a frame that cannot be made one open surface with one boundary
  kMissingTexture = 8,   // a referenced texture image does not exist or cannot be decoded
  kInvalidArgument = 9,  // a caller-supplied option or value outside its domain
  kNumerical = 10,       // a numerical method failed (singular system, NaN produced)
  kNotConverged = 11,    // an iteration stopped before meeting its tolerance
  kOutOfRange = 12,      // a request outside what the data can serve (e.g. t too far out)
  kBufferTooSmall = 13,  // a caller-owned output buffer is smaller than the data (the call says what is needed)
  kOutOfMemory = 14,     // an allocation failed
  kInternal = 15,        // a failure that is none of the above (a bug in facemorph: please report it)
  kLimit = 16,           // an input that needs more than the caller's limits allow (DecoderLimits: grid, keyframes, texture, memory)
  kClosedHandle = 17,    // a C API handle used after it was closed or destroyed (or closed twice)
};

// Short stable name of a code, e.g. "truncated"; never null.
constexpr const char* error_code_name(ErrorCode code) noexcept {
  switch (code) {
    case ErrorCode::kOk: return "ok";
    case ErrorCode::kIo: return "io";
    case ErrorCode::kParse: return "parse";
    case ErrorCode::kTruncated: return "truncated";
    case ErrorCode::kCorrupt: return "corrupt";
    case ErrorCode::kUnsupported: return "unsupported";
    case ErrorCode::kInvalidMesh: return "invalid-mesh";
    case ErrorCode::kNotADisk: return "not-a-disk";
    case ErrorCode::kMissingTexture: return "missing-texture";
    case ErrorCode::kInvalidArgument: return "invalid-argument";
    case ErrorCode::kNumerical: return "numerical";
    case ErrorCode::kNotConverged: return "not-converged";
    case ErrorCode::kOutOfRange: return "out-of-range";
    case ErrorCode::kBufferTooSmall: return "buffer-too-small";
    case ErrorCode::kOutOfMemory: return "out-of-memory";
    case ErrorCode::kInternal: return "internal";
    case ErrorCode::kLimit: return "limit";
    case ErrorCode::kClosedHandle: return "closed-handle";
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
