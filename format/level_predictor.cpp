#include "format/level_predictor.hpp"

#include "format/error.hpp"
#include "format/lattice_prediction.hpp"

#include <limits>

namespace facemorph::format {

namespace {

// ⌊a / b⌋ for b > 0 (C++ division truncates towards zero).
int64_t floor_divide(int64_t a, int64_t b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

// The prediction at coding position k; `code(e)` reads element e, decoded already.
template <typename Code>
int64_t level_prediction(const LevelOrder& order, size_t k, Code code) {
  const std::array<int32_t, 4>& from = order.from[k];
  // Nothing around it: the node coded before.
  const auto coded_before = [&] { return k == 0 ? int64_t{0} : code(static_cast<size_t>(order.element[k - 1])); };
  if (order.gradient[k]) {
    return lattice_prediction(from[0], from[1], from[2], code, [](int64_t a, int64_t b, int64_t c) { return a + b - c; }, coded_before);
  }
  int64_t sum = 0, m = 0;
  for (const int32_t e : from) {
    if (e >= 0) sum += code(static_cast<size_t>(e)), ++m;
  }
  // The mean rounded half up, exactly: ⌊(2 sum + m) / 2m⌋.
  return m > 0 ? floor_divide(2 * sum + m, 2 * m) : coded_before();
}

}  // namespace

LevelOrder level_order(std::span<const std::array<int32_t, 2>> cells, std::span<const int32_t> index_at, int width) {
  if (width <= 0 || index_at.size() != static_cast<size_t>(width) * static_cast<size_t>(width))
    throw Error(ErrorCode::kInvalidArgument, "a level order needs a width × width index table");
  const auto at = [&](int i, int j) -> int32_t {
    return (i < 0 || j < 0 || i >= width || j >= width) ? -1 : index_at[static_cast<size_t>(j) * static_cast<size_t>(width) + static_cast<size_t>(i)];
  };
  for (size_t e = 0; e < cells.size(); ++e) {
    if (at(cells[e][0], cells[e][1]) != static_cast<int32_t>(e)) throw Error(ErrorCode::kInvalidArgument, "a lattice cell its index table does not name");
  }
  LevelOrder order;
  std::vector<int32_t> position(cells.size(), -1);
  std::vector<int> spacing_of;  // per coding position: its class's spacing, for the context
  // Sized once: grown by push_back the tables held 53 bytes an interior node, not 33 (fmdec's peak at N = 1025).
  order.element.reserve(cells.size());
  order.from.reserve(cells.size());
  order.gradient.reserve(cells.size());
  spacing_of.reserve(cells.size());
  for (auto* table : {&order.context.left, &order.context.up, &order.context.up_left}) table->reserve(cells.size());
  const auto add = [&](size_t e, std::array<int32_t, 4> from, bool gradient, int spacing) {
    position[e] = static_cast<int32_t>(order.size());
    order.element.push_back(static_cast<int32_t>(e));
    order.from.push_back(from);
    order.gradient.push_back(gradient ? 1 : 0);
    spacing_of.push_back(spacing);
  };
  const int coarse = kCoarseSpacing;
  for (size_t e = 0; e < cells.size(); ++e) {
    const auto [i, j] = cells[e];
    if (i % coarse == 0 && j % coarse == 0) add(e, {at(i - coarse, j), at(i, j - coarse), at(i - coarse, j - coarse), -1}, true, coarse);
  }
  for (int s = coarse / 2; s >= 1; s /= 2) {
    for (int pass = 0; pass < 2; ++pass) {  // 0: odd both ways, from the diagonals; 1: odd one way, from the axes
      for (size_t e = 0; e < cells.size(); ++e) {
        const auto [i, j] = cells[e];
        if (i % s != 0 || j % s != 0) continue;
        const bool odd_i = (i / s) % 2 != 0, odd_j = (j / s) % 2 != 0;
        if (pass == 0 ? !(odd_i && odd_j) : (odd_i == odd_j)) continue;
        if (pass == 0) add(e, {at(i - s, j - s), at(i + s, j - s), at(i - s, j + s), at(i + s, j + s)}, false, 2 * s);
        else add(e, {at(i - s, j), at(i + s, j), at(i, j - s), at(i, j + s)}, false, 2 * s);
      }
    }
  }
  if (order.size() != cells.size()) throw Error(ErrorCode::kInvalidArgument, "a lattice cell on no level");
  for (size_t k = 0; k < order.size(); ++k) {
    for (const int32_t e : order.from[k]) {
      if (e >= 0 && position[static_cast<size_t>(e)] >= static_cast<int32_t>(k))
        throw Error(ErrorCode::kInternal, "a level predictor reading a node not yet decoded");
    }
    const auto [i, j] = cells[static_cast<size_t>(order.element[k])];
    const int s = spacing_of[k];
    const int32_t left = at(i - s, j), up = at(i, j - s);
    order.context.left.push_back(left >= 0 ? position[static_cast<size_t>(left)] : -1);
    order.context.up.push_back(up >= 0 ? position[static_cast<size_t>(up)] : -1);
    order.context.up_left.push_back(-1);
  }
  return order;
}

std::vector<int64_t> level_residuals(std::span<const int32_t> codes, const LevelOrder& order) {
  if (codes.size() != order.size()) throw Error(ErrorCode::kInvalidArgument, "a level order of another array's size");
  std::vector<int64_t> out(codes.size());
  for (size_t k = 0; k < order.size(); ++k) {
    out[k] = codes[static_cast<size_t>(order.element[k])] - level_prediction(order, k, [&](size_t e) { return int64_t{codes[e]}; });
  }
  return out;
}

std::vector<int32_t> codes_from_level_residuals(std::span<const int64_t> residuals, const LevelOrder& order, const std::string& source) {
  if (residuals.size() != order.size()) throw Error(ErrorCode::kInvalidArgument, "a level order of another array's size");
  std::vector<int32_t> codes(residuals.size());
  for (size_t k = 0; k < order.size(); ++k) {
    // Predictions of int32 codes are below 2^33 and residuals at most 2^34 (§7.3): no overflow in 64 bits.
    const int64_t code = level_prediction(order, k, [&](size_t e) { return int64_t{codes[e]}; }) + residuals[k];
    if (code < std::numeric_limits<int32_t>::min() || code > std::numeric_limits<int32_t>::max()) {
      throw Error(ErrorCode::kCorrupt, source + ": a field code outside 32 bits (levels predictor, element " +
                                           std::to_string(order.element[k]) + ")");
    }
    codes[static_cast<size_t>(order.element[k])] = static_cast<int32_t>(code);
  }
  return codes;
}

}  // namespace facemorph::format
