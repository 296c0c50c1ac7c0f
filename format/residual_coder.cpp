#include "format/residual_coder.hpp"

#include "facemorph/error.hpp"
#include "format/zstd_frame.hpp"

#include <algorithm>
#include <limits>

namespace facemorph::format {

namespace {

constexpr int kMaxVarintBytes = 5;

const LatticeNeighbours& checked_lattice(const LatticeNeighbours* lattice, size_t size) {
  if (lattice == nullptr || lattice->size() != size || lattice->up.size() != size || lattice->up_left.size() != size) {
    throw Error(ErrorCode::kInvalidArgument, "a lattice predictor needs the array's neighbour table");
  }
  return *lattice;
}

// The prediction of element i from the codes before it; `code(j)` reads an earlier element.
template <typename Code>
int64_t predict(size_t i, SpatialPredictor predictor, const LatticeNeighbours* lattice, Code code) {
  const auto previous = [&] { return i == 0 ? int64_t{0} : code(i - 1); };
  switch (predictor) {
    case SpatialPredictor::kNone:
      return 0;
    case SpatialPredictor::kPrevious:
      return previous();
    case SpatialPredictor::kGradient:
    case SpatialPredictor::kMedian: {
      const int32_t l = lattice->left[i], u = lattice->up[i], ul = lattice->up_left[i];
      if (l >= 0 && u >= 0 && ul >= 0) {
        const int64_t a = code(static_cast<size_t>(l)), b = code(static_cast<size_t>(u)), c = code(static_cast<size_t>(ul));
        if (predictor == SpatialPredictor::kGradient) return a + b - c;
        // LOCO-I: an edge above or to the left picks the other neighbour; else the plane.
        if (c >= std::max(a, b)) return std::min(a, b);
        if (c <= std::min(a, b)) return std::max(a, b);
        return a + b - c;
      }
      if (l >= 0) return code(static_cast<size_t>(l));
      if (u >= 0) return code(static_cast<size_t>(u));
      return previous();
    }
  }
  throw Error(ErrorCode::kInvalidArgument, "unknown spatial predictor");
}

void check_order(const LatticeNeighbours& lattice) {
  for (size_t i = 0; i < lattice.size(); ++i) {
    for (int32_t n : {lattice.left[i], lattice.up[i], lattice.up_left[i]}) {
      if (n >= static_cast<int64_t>(i)) throw Error(ErrorCode::kInvalidArgument, "a lattice neighbour that comes after its element");
    }
  }
}

uint64_t zigzag(int64_t v) { return (static_cast<uint64_t>(v) << 1) ^ static_cast<uint64_t>(v >> 63); }
int64_t unzigzag(uint64_t u) { return static_cast<int64_t>(u >> 1) ^ -static_cast<int64_t>(u & 1); }

}  // namespace

std::vector<int64_t> spatial_residuals(std::span<const int32_t> codes, SpatialPredictor predictor, const LatticeNeighbours* lattice) {
  if (uses_lattice(predictor)) check_order(checked_lattice(lattice, codes.size()));
  std::vector<int64_t> out(codes.size());
  for (size_t i = 0; i < codes.size(); ++i) {
    out[i] = codes[i] - predict(i, predictor, lattice, [&](size_t j) { return int64_t{codes[j]}; });
  }
  return out;
}

std::vector<int32_t> codes_from_residuals(std::span<const int64_t> residuals, SpatialPredictor predictor, const LatticeNeighbours* lattice,
                                          const std::string& source) {
  if (uses_lattice(predictor)) check_order(checked_lattice(lattice, residuals.size()));
  std::vector<int32_t> codes(residuals.size());
  for (size_t i = 0; i < residuals.size(); ++i) {
    // Residuals are below 2^35 and predictions of int32 codes below 2^33: no overflow in 64 bits.
    const int64_t code = predict(i, predictor, lattice, [&](size_t j) { return int64_t{codes[j]}; }) + residuals[i];
    if (code < std::numeric_limits<int32_t>::min() || code > std::numeric_limits<int32_t>::max()) {
      throw Error(ErrorCode::kCorrupt, source + ": a field code outside 32 bits");
    }
    codes[i] = static_cast<int32_t>(code);
  }
  return codes;
}

std::vector<uint8_t> encode_residual_stream(std::span<const std::vector<int64_t>> arrays, int level) {
  std::vector<uint8_t> varints;
  for (const std::vector<int64_t>& residuals : arrays) {
    for (int64_t r : residuals) {
      uint64_t u = zigzag(r);
      if (u >> (7 * kMaxVarintBytes)) throw Error(ErrorCode::kInvalidArgument, "a residual beyond 2^35");
      while (u >= 0x80) {
        varints.push_back(static_cast<uint8_t>(u | 0x80));
        u >>= 7;
      }
      varints.push_back(static_cast<uint8_t>(u));
    }
  }
  return compress_frame(varints, level);
}

std::vector<std::vector<int64_t>> decode_residual_stream(std::span<const uint8_t> bytes, std::span<const size_t> lengths, const std::string& source) {
  size_t total = 0;
  for (size_t n : lengths) {
    if (n > (size_t{1} << 30) || total > (size_t{1} << 30)) throw Error(ErrorCode::kCorrupt, source + ": field arrays too long");
    total += n;
  }
  // Every residual takes 1 to 5 bytes: a frame announcing more or less cannot be right, and the
  // bound keeps a forged size from allocating more than the arrays could need.
  const std::optional<uint64_t> announced = announced_size(bytes);
  if (!announced) throw Error(ErrorCode::kCorrupt, source + ": residual payload is not a zstd frame that announces its size");
  if (*announced < total || *announced > uint64_t{kMaxVarintBytes} * total) {
    throw Error(ErrorCode::kCorrupt, source + ": residual payload announces " + std::to_string(*announced) + " bytes for " + std::to_string(total) +
                                         " residuals");
  }
  // Allocated as it decompresses: an announcement the frame cannot back costs nothing.
  const std::optional<std::vector<uint8_t>> decompressed = decompress_frame_growing(bytes, *announced);
  if (!decompressed) throw Error(ErrorCode::kCorrupt, source + ": damaged residual payload");
  const std::vector<uint8_t>& varints = *decompressed;
  std::vector<std::vector<int64_t>> out;
  size_t at = 0;
  for (size_t n : lengths) {
    std::vector<int64_t> residuals(n);
    for (size_t i = 0; i < n; ++i) {
      uint64_t u = 0;
      for (int b = 0;; ++b) {
        if (at == varints.size()) throw Error(ErrorCode::kCorrupt, source + ": the residuals end early");
        if (b == kMaxVarintBytes) throw Error(ErrorCode::kCorrupt, source + ": a residual longer than 5 bytes");
        const uint8_t byte = varints[at++];
        u |= static_cast<uint64_t>(byte & 0x7f) << (7 * b);
        if (!(byte & 0x80)) break;
      }
      residuals[i] = unzigzag(u);
    }
    out.push_back(std::move(residuals));
  }
  if (at != varints.size()) throw Error(ErrorCode::kCorrupt, source + ": bytes after the last residual");
  return out;
}

}  // namespace facemorph::format
