#include "format/ranged_patches.hpp"

#include "format/error.hpp"

namespace facemorph::format {

namespace {

// Times sit on 64ths of a frame period; a patch's is almost always a whole number of frames after
// the one before (a captured frame's), which the stream codes as that number alone.
constexpr int64_t kTimeSteps = 64;

bool moving(const PatchLattice& l, int32_t i) { return !l.element.empty() && l.element[static_cast<size_t>(i)] >= 0; }

// Node i's flag context: its left, up, up-left and up-right neighbours' flags (coded before it),
// and its own flag in the previous patch where that patch has the same lattice.
int occupancy_context(const PatchLattice& current, const PatchLattice& previous, int32_t i) {
  const int32_t c = current.lattice, a = i % c, b = i / c;
  const int left = a > 0 && moving(current, i - 1);
  const int up = b > 0 && moving(current, i - c);
  const int up_left = a > 0 && b > 0 && moving(current, i - c - 1);
  const int up_right = a + 1 < c && b > 0 && moving(current, i - c + 1);
  const int before = previous.lattice == c && moving(previous, i);
  return left + 2 * up + 4 * up_left + 8 * up_right + 16 * before;
}

// The two values whose sizes and signs choose component `k` of moving node `n` (lattice node i)'s
// models (§7.3's context): a, its left neighbour's code, or where that one is still the previous
// moving node's (0 for the first); b, the same node's code in the previous patch where that patch
// has the same lattice and moved it (patches of one interval move the same region alike), else its
// upper neighbour's, else a.
std::pair<int64_t, int64_t> code_context(const PatchLattice& current, const PatchLattice& previous, size_t n, int32_t i, int k) {
  const int32_t c = current.lattice, a = i % c, b = i / c;
  const auto code_at = [k](const PatchLattice& l, int32_t node) { return l.codes[static_cast<size_t>(l.element[static_cast<size_t>(node)])][k]; };
  const int64_t left = a > 0 && moving(current, i - 1) ? code_at(current, i - 1) : n > 0 ? current.codes[n - 1][k] : 0;
  if (previous.lattice == c && moving(previous, i)) return {left, code_at(previous, i)};
  return {left, b > 0 && moving(current, i - c) ? code_at(current, i - c) : left};
}

}  // namespace

void PatchStreamWriter::add(const CodedPatch& p) {
  const auto invalid = [](const std::string& what) { throw Error(ErrorCode::kInvalidArgument, "a range-coded patch: " + what); };
  if (p.time_change < 1) invalid("a time change below 1");
  if (p.lattice < 2 || p.lattice > kMaxRangedPatchLattice) invalid("a lattice outside 2 … 129");
  if (p.codes.size() != p.nodes.size()) invalid("one code triple per node needed");
  const int32_t c = p.lattice, nodes = c * c;
  for (size_t k = 0; k < p.nodes.size(); ++k) {
    if (p.nodes[k] < 0 || p.nodes[k] >= nodes || (k > 0 && p.nodes[k] <= p.nodes[k - 1])) invalid("nodes not increasing within C²");
    for (int64_t code : p.codes[k]) {
      if (code < -kMaxRangedResidual || code > kMaxRangedResidual) invalid("a code beyond 2^34");
    }
  }
  const int64_t frames = p.time_change / kTimeSteps, remainder = p.time_change % kTimeSteps;
  stream_.decision(models_.off_frame, remainder != 0);
  stream_.number(models_.frames, remainder != 0 ? frames : frames - 1);
  if (remainder != 0) stream_.number(models_.remainder, remainder);
  stream_.decision(models_.new_lattice, c != previous_.lattice);
  if (c != previous_.lattice) stream_.number(models_.lattice, c);
  stream_.decision(models_.empty, p.nodes.empty());
  PatchLattice current{c, {}, p.codes};
  if (!p.nodes.empty()) {
    // Flags in node order, each under the flags before it: `element` fills as they are coded.
    current.element.assign(static_cast<size_t>(nodes), -1);
    size_t next = 0;
    for (int32_t i = 0; i < nodes; ++i) {
      const bool moves = next < p.nodes.size() && p.nodes[next] == i;
      stream_.decision(models_.occupied[occupancy_context(current, previous_, i)], moves);
      if (moves) current.element[static_cast<size_t>(i)] = static_cast<int32_t>(next++);
    }
    for (size_t n = 0; n < p.nodes.size(); ++n) {
      for (int k = 0; k < 3; ++k) {
        const auto [a, b] = code_context(current, previous_, n, p.nodes[n], k);
        stream_.residual(models_.codes[k], a, b, p.codes[n][k]);
      }
    }
  }
  previous_ = std::move(current);
}

PatchStreamReader::PatchStreamReader(std::span<const uint8_t> bytes, std::string source)
    : stream_(bytes, source), source_(std::move(source)) {}

int64_t PatchStreamReader::time_change() {
  const bool off_frame = stream_.decision(models_.off_frame);
  const int64_t coded = stream_.number(models_.frames);
  if (coded < 0) throw Error(ErrorCode::kCorrupt, source_ + ": a patch's time change of " + std::to_string(coded) + " frames");
  const int64_t frames = off_frame ? coded : coded + 1;
  int64_t remainder = 0;
  if (off_frame) {
    remainder = stream_.number(models_.remainder);
    if (remainder < 1 || remainder >= kTimeSteps)
      throw Error(ErrorCode::kCorrupt, source_ + ": a patch time's remainder " + std::to_string(remainder) + " outside 1..63");
  }
  return frames * kTimeSteps + remainder;  // frames < 2^42 (number's bound): no overflow
}

int32_t PatchStreamReader::lattice() {
  int64_t c = previous_.lattice;
  if (stream_.decision(models_.new_lattice)) c = stream_.number(models_.lattice);
  if (c < 2 || c > kMaxRangedPatchLattice)
    throw Error(ErrorCode::kCorrupt, source_ + ": a patch's lattice " + std::to_string(c) + " outside 2..129");
  current_ = PatchLattice{static_cast<int32_t>(c), {}, {}};
  return current_.lattice;
}

size_t PatchStreamReader::occupancy() {
  if (current_.lattice == 0) throw Error(ErrorCode::kInvalidArgument, "PatchStreamReader: occupancy() before lattice()");
  if (stream_.decision(models_.empty)) return 0;
  const int32_t nodes = current_.lattice * current_.lattice;
  current_.element.assign(static_cast<size_t>(nodes), -1);
  int32_t count = 0;
  for (int32_t i = 0; i < nodes; ++i) {
    if (stream_.decision(models_.occupied[occupancy_context(current_, previous_, i)])) current_.element[static_cast<size_t>(i)] = count++;
  }
  if (count == 0) throw Error(ErrorCode::kCorrupt, source_ + ": a patch said to move nodes moves none");
  return static_cast<size_t>(count);
}

void PatchStreamReader::nodes_and_codes(std::span<int32_t> nodes, std::span<std::array<int64_t, 3>> codes) {
  size_t found = 0;
  for (size_t i = 0; i < current_.element.size(); ++i) {
    if (current_.element[i] < 0) continue;
    if (found == nodes.size()) throw Error(ErrorCode::kInvalidArgument, "PatchStreamReader: fewer nodes asked for than occupancy() found");
    nodes[found++] = static_cast<int32_t>(i);
  }
  if (found != nodes.size() || codes.size() != nodes.size())
    throw Error(ErrorCode::kInvalidArgument, "PatchStreamReader: spans of another size than occupancy()'s count");
  current_.codes.resize(nodes.size());
  for (size_t n = 0; n < nodes.size(); ++n) {
    for (int k = 0; k < 3; ++k) {
      const auto [a, b] = code_context(current_, previous_, n, nodes[n], k);
      current_.codes[n][k] = stream_.residual(models_.codes[k], a, b);
    }
    codes[n] = current_.codes[n];
  }
  previous_ = std::move(current_);
  current_ = PatchLattice{};
}

}  // namespace facemorph::format
