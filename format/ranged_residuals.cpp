#include "format/ranged_residuals.hpp"

#include "format/error.hpp"
#include "format/range_coder.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>

namespace facemorph::format {

namespace {

// The numbers below are the format's (spec/container.md §7.4).
constexpr int kMagnitudeClasses = 6;  // by the magnitudes of two residuals coded before
constexpr int kSignClasses = 9;       // by the signs of the same two
constexpr int kUnary = 8;             // "larger than j" decisions before the escape
constexpr int kEscapeModels = 12;     // Exp-Golomb prefix decisions with a model each (later ones share the last)
constexpr int kMaxEscapeBits = 34;    // |r| ≤ 2^34 needs at most 34 suffix bits
// The likeliest decision costs at least −log2(4061/4096) = 0.0124 bits (BitModel's bounds): a byte
// holds fewer than 650 residuals, so a stream announcing more is refused before anything is allocated.
constexpr size_t kMaxResidualsPerByte = 650;

using Models = ResidualModels;
static_assert(std::tuple_size_v<decltype(Models::zero)> == kMagnitudeClasses && std::tuple_size_v<decltype(Models::sign)> == kSignClasses);
static_assert(std::tuple_size_v<decltype(Models::larger)> == kMagnitudeClasses &&
              std::tuple_size_v<decltype(Models::larger)::value_type> == kUnary);
static_assert(std::tuple_size_v<decltype(Models::escape)> == kEscapeModels);

uint64_t magnitude(int64_t r) { return r < 0 ? uint64_t{0} - static_cast<uint64_t>(r) : static_cast<uint64_t>(r); }

// The two residuals coded before element i that choose its models: on a lattice its left and upper
// neighbours (the element before it where it has no left one; the left one again where it has no
// upper one); in a sequence the two elements before it. An absent one counts as 0.
struct Context {
  int magnitude_class, sign_class;
};

Context context_from(int64_t a, int64_t b) {
  const uint64_t m = std::min<uint64_t>(magnitude(a), 64) + std::min<uint64_t>(magnitude(b), 64);
  const int magnitude_class = m <= 2 ? static_cast<int>(m) : m <= 4 ? 3 : m <= 8 ? 4 : 5;
  const auto sign = [](int64_t v) { return v < 0 ? 0 : v == 0 ? 1 : 2; };
  return {magnitude_class, 3 * sign(a) + sign(b)};
}

Context context_of(std::span<const int64_t> coded, size_t i, const LatticeNeighbours* lattice) {
  int64_t a = 0, b = 0;
  if (lattice) {
    const int32_t left = lattice->left[i], up = lattice->up[i];
    a = left >= 0 ? coded[static_cast<size_t>(left)] : i > 0 ? coded[i - 1] : 0;
    b = up >= 0 ? coded[static_cast<size_t>(up)] : a;
  } else {
    a = i > 0 ? coded[i - 1] : 0;
    b = i > 1 ? coded[i - 2] : 0;
  }
  return context_from(a, b);
}

// One residual's decisions, the same code for all three sides: the encoder passes the residual and
// codes its decisions; the decoder ignores it and reads them; the estimator counts their bits.
template <typename Side>
int64_t code_residual(Side& side, Models& m, Context c, int64_t r) {
  if (!side.bit(m.zero[c.magnitude_class], r != 0)) return 0;
  const bool negative = side.bit(m.sign[c.sign_class], r < 0);
  const uint64_t rest = magnitude(r) - 1;  // the encoder's (r ≠ 0 there); unused by the decoder
  uint64_t value = kUnary;
  for (int j = 0; j < kUnary; ++j) {
    if (!side.bit(m.larger[c.magnitude_class][j], rest > static_cast<uint64_t>(j))) {
      value = static_cast<uint64_t>(j);
      break;
    }
  }
  if (value == kUnary) {
    // Exp-Golomb of rest − kUnary: n ones and a zero, then the n bits of rest − kUnary + 1 below its top.
    const uint64_t v = rest - kUnary + 1;
    const int bits = std::bit_width(v) - 1;
    int n = 0;
    while (side.bit(m.escape[std::min(n, kEscapeModels - 1)], n < bits)) {
      if (++n > kMaxEscapeBits) side.corrupt("an escape longer than 34 bits");
    }
    uint64_t low = 0;
    if (n > 32) low = uint64_t{side.direct(static_cast<uint32_t>(v >> 32), n - 32)} << 32;
    low |= side.direct(static_cast<uint32_t>(v), std::min(n, 32));
    value = kUnary + ((uint64_t{1} << n) | low) - 1;
  }
  const uint64_t size = value + 1;
  if (size > static_cast<uint64_t>(kMaxRangedResidual)) side.corrupt("a residual beyond 2^34");
  return negative ? -static_cast<int64_t>(size) : static_cast<int64_t>(size);
}

// Codes one array in place (the decoder's values are filled in as they are read).
template <typename Side>
void code_array(Side& side, Models& models, std::span<int64_t> values, const LatticeNeighbours* lattice) {
  for (size_t i = 0; i < values.size(); ++i) values[i] = code_residual(side, models, context_of(values, i, lattice), values[i]);
}

uint32_t low_bits(uint32_t value, int count) { return count >= 32 ? value : value & ((uint32_t{1} << count) - 1); }

constexpr int kNumberLengthDecisions = 6;  // the bit length, 0..63, of which 0..kMaxNumberBits are valid
static_assert(std::tuple_size_v<decltype(NumberModels::length)> == (1 << kNumberLengthDecisions));

// One signed number's decisions (spec/container.md §7.5), for all three sides as code_residual.
template <typename Side>
int64_t code_number(Side& side, NumberModels& m, int64_t value) {
  const uint64_t size = magnitude(value);  // the encoder's; unused by the decoder
  const auto wanted = static_cast<uint32_t>(std::bit_width(size));
  uint32_t n = 0, node = 1;
  for (int b = kNumberLengthDecisions - 1; b >= 0; --b) {
    const uint32_t bit = side.bit(m.length[node], ((wanted >> b) & 1u) != 0) ? 1 : 0;
    node = 2 * node + bit;
    n = (n << 1) | bit;
  }
  if (n > static_cast<uint32_t>(kMaxNumberBits)) side.corrupt("a number longer than 42 bits");
  if (n == 0) return 0;
  const bool negative = side.direct(value < 0 ? 1 : 0, 1) != 0;
  const int below = static_cast<int>(n) - 1;  // the bits under the top one, which is 1
  uint64_t low = 0;
  if (below > 32) low = uint64_t{side.direct(static_cast<uint32_t>(size >> 32), below - 32)} << 32;
  low |= side.direct(static_cast<uint32_t>(size), std::min(below, 32));
  const uint64_t decoded = (uint64_t{1} << below) | low;
  return negative ? -static_cast<int64_t>(decoded) : static_cast<int64_t>(decoded);
}

struct EncoderSide {
  RangeEncoder& coder;
  bool bit(BitModel& model, bool bit) {
    coder.encode(model, bit ? 1 : 0);
    return bit;
  }
  uint32_t direct(uint32_t value, int count) {
    if (count > 0) coder.encode_direct(low_bits(value, count), count);
    return low_bits(value, count);
  }
  [[noreturn]] void corrupt(const char* what) { throw Error(ErrorCode::kInvalidArgument, what); }
};

struct DecoderSide {
  RangeDecoder& coder;
  const std::string& source;
  bool bit(BitModel& model, bool) { return coder.decode(model) != 0; }
  uint32_t direct(uint32_t, int count) { return count > 0 ? coder.decode_direct(count) : 0; }
  [[noreturn]] void corrupt(const char* what) { throw Error(ErrorCode::kCorrupt, source + ": " + what); }
};

// log2 of the probability of each decision BitModel can code: of a 0 (p0 / 4096) and of a 1
// (1 − p0 / 4096), for every p0, computed as the estimate once computed them a decision at a time,
// so the same doubles and the same sums to the bit (RangedResiduals.TheEstimateIsEachDecisionsLogToTheBit)
// without a log2 a decision: the estimate is laid out for each predictor of each array, each dead
// zone and each candidate of the encoder's choice by bytes (spec/method.md §7.14), and its log2s were
// 3.6% of ict24's encode.
struct DecisionLogs {
  std::array<double, BitModel::kOne + 1> zero, one;
  DecisionLogs() {
    for (uint32_t p = 0; p <= BitModel::kOne; ++p) {
      const double p0 = p / static_cast<double>(BitModel::kOne);
      zero[p] = std::log2(p0);
      one[p] = std::log2(1 - p0);
    }
  }
};

const DecisionLogs& decision_logs() {
  static const DecisionLogs logs;
  return logs;
}

struct EstimatorSide {
  double bits = 0;
  const DecisionLogs& logs = decision_logs();
  bool bit(BitModel& model, bool bit) {
    const uint32_t p0 = model.p0();
    bits -= bit ? logs.one[p0] : logs.zero[p0];
    model.update(bit ? 1 : 0);
    return bit;
  }
  uint32_t direct(uint32_t value, int count) {
    bits += count;
    return low_bits(value, count);
  }
  [[noreturn]] void corrupt(const char* what) { throw Error(ErrorCode::kInvalidArgument, what); }
};

const LatticeNeighbours* checked(const LatticeNeighbours* lattice, size_t size) {
  if (!lattice) return nullptr;
  if (lattice->size() != size || lattice->up.size() != size || lattice->up_left.size() != size) {
    throw Error(ErrorCode::kInvalidArgument, "a lattice table of another size than its array");
  }
  for (size_t i = 0; i < size; ++i) {
    if (lattice->left[i] >= static_cast<int64_t>(i) || lattice->up[i] >= static_cast<int64_t>(i)) {
      throw Error(ErrorCode::kInvalidArgument, "a lattice neighbour that comes after its element");
    }
  }
  return lattice;
}

void check_layout(size_t arrays, std::span<const LatticeNeighbours* const> lattices, std::span<const uint8_t> model_sets) {
  if (lattices.size() != arrays || model_sets.size() != arrays)
    throw Error(ErrorCode::kInvalidArgument, "one lattice and one model set per residual array needed");
  for (size_t a = 0; a < arrays; ++a) {
    if (model_sets[a] > a) throw Error(ErrorCode::kInvalidArgument, "an array's model set must be its own or an earlier array's");
  }
}

// The models a stream starts from: the caller's, fresh ones where it has none yet.
std::vector<Models>& starting_models(std::vector<Models>& models, size_t arrays) {
  if (models.empty()) models.resize(arrays);
  if (models.size() != arrays) throw Error(ErrorCode::kInvalidArgument, "one set of carried models per residual array needed");
  return models;
}

}  // namespace

void RangedStreamWriter::decision(BitModel& model, bool bit) { coder_.encode(model, bit ? 1 : 0); }

void RangedStreamWriter::number(NumberModels& models, int64_t value) {
  if (magnitude(value) >= (uint64_t{1} << kMaxNumberBits))
    throw Error(ErrorCode::kInvalidArgument, "a number beyond 2^42 for the range coder");
  EncoderSide side{coder_};
  code_number(side, models, value);
}

void RangedStreamWriter::residual_arrays(std::span<const std::vector<int64_t>> arrays, std::span<const LatticeNeighbours* const> lattices,
                                         std::span<const uint8_t> model_sets, std::vector<ResidualModels>& carried) {
  check_layout(arrays.size(), lattices, model_sets);
  EncoderSide side{coder_};
  std::vector<Models>& models = starting_models(carried, arrays.size());
  for (size_t a = 0; a < arrays.size(); ++a) {
    for (int64_t r : arrays[a]) {
      if (magnitude(r) > static_cast<uint64_t>(kMaxRangedResidual)) throw Error(ErrorCode::kInvalidArgument, "a residual beyond 2^34");
    }
    std::vector<int64_t> values = arrays[a];
    code_array(side, models[model_sets[a]], std::span<int64_t>(values), checked(lattices[a], values.size()));
  }
}

void RangedStreamWriter::residual(ResidualModels& models, int64_t a, int64_t b, int64_t r) {
  if (magnitude(r) > static_cast<uint64_t>(kMaxRangedResidual)) throw Error(ErrorCode::kInvalidArgument, "a residual beyond 2^34");
  EncoderSide side{coder_};
  code_residual(side, models, context_from(a, b), r);
}

RangedStreamReader::RangedStreamReader(std::span<const uint8_t> bytes, std::string source)
    : coder_(bytes, source), source_(std::move(source)), bytes_(bytes.size()) {}

bool RangedStreamReader::decision(BitModel& model) { return coder_.decode(model) != 0; }

int64_t RangedStreamReader::number(NumberModels& models) {
  DecoderSide side{coder_, source_};
  return code_number(side, models, 0);
}

int64_t RangedStreamReader::residual(ResidualModels& models, int64_t a, int64_t b) {
  DecoderSide side{coder_, source_};
  return code_residual(side, models, context_from(a, b), 0);
}

std::vector<std::vector<int64_t>> RangedStreamReader::residual_arrays(std::span<const size_t> lengths,
                                                                      std::span<const LatticeNeighbours* const> lattices,
                                                                      std::span<const uint8_t> model_sets,
                                                                      std::vector<ResidualModels>& carried) {
  check_layout(lengths.size(), lattices, model_sets);
  // Refused before anything is allocated: more residuals than the whole stream can hold.
  const size_t most = kMaxResidualsPerByte * bytes_;
  for (size_t n : lengths) {
    if (n > most - residuals_read_)
      throw Error(ErrorCode::kCorrupt, source_ + ": " + std::to_string(bytes_) + " range-coded bytes cannot hold the arrays' values");
    residuals_read_ += n;
  }
  DecoderSide side{coder_, source_};
  std::vector<Models>& models = starting_models(carried, lengths.size());
  std::vector<std::vector<int64_t>> out;
  for (size_t a = 0; a < lengths.size(); ++a) {
    std::vector<int64_t> values(lengths[a], 0);
    code_array(side, models[model_sets[a]], std::span<int64_t>(values), checked(lattices[a], values.size()));
    out.push_back(std::move(values));
  }
  return out;
}

std::vector<uint8_t> encode_ranged_residuals(std::span<const std::vector<int64_t>> arrays,
                                             std::span<const LatticeNeighbours* const> lattices, std::span<const uint8_t> model_sets,
                                             std::vector<ResidualModels>* carried) {
  RangedStreamWriter stream;
  std::vector<Models> fresh;
  stream.residual_arrays(arrays, lattices, model_sets, carried ? *carried : fresh);
  return stream.finish();
}

std::vector<std::vector<int64_t>> decode_ranged_residuals(std::span<const uint8_t> bytes, std::span<const size_t> lengths,
                                                          std::span<const LatticeNeighbours* const> lattices,
                                                          std::span<const uint8_t> model_sets, const std::string& source,
                                                          std::vector<ResidualModels>* carried) {
  RangedStreamReader stream(bytes, source);
  std::vector<Models> fresh;
  std::vector<std::vector<int64_t>> out = stream.residual_arrays(lengths, lattices, model_sets, carried ? *carried : fresh);
  stream.expect_end();
  return out;
}

double ranged_residual_bits(std::span<const int64_t> residuals, const LatticeNeighbours* lattice) {
  EstimatorSide side;
  Models models;
  std::vector<int64_t> values(residuals.begin(), residuals.end());
  code_array(side, models, std::span<int64_t>(values), checked(lattice, values.size()));
  return side.bits;
}

}  // namespace facemorph::format
