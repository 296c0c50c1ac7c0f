// Small text-scanning helpers shared by the OBJ, MTL, PLY and CSV readers.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>

namespace facemorph::text {

inline bool is_space(char c) { return c == ' ' || c == '\n' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

// Walks a buffer line by line; lines exclude the terminator ('\n', "\r\n").
class LineScanner {
 public:
  explicit LineScanner(std::string_view text) : text_(text) {}
  bool next(std::string_view& line) {
    if (pos_ >= text_.size()) return false;
    const size_t end = text_.find('\n', pos_);
    const size_t stop = end == std::string_view::npos ? text_.size() : end;
    line = text_.substr(pos_, stop - pos_);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos_ = stop == text_.size() ? stop : stop + 1;
    ++line_number_;
    return true;
  }
  size_t line_number() const { return line_number_; }
  size_t position() const { return pos_; }

 private:
  std::string_view text_;
  size_t pos_ = 0;
  size_t line_number_ = 0;
};

// Pops the next whitespace-delimited token; empty when none is left.
inline std::string_view next_token(std::string_view& rest) {
  size_t i = 0;
  while (i < rest.size() && is_space(rest[i])) ++i;
  size_t j = i;
  while (j < rest.size() && !is_space(rest[j])) ++j;
  std::string_view token = rest.substr(i, j - i);
  rest.remove_prefix(j);
  return token;
}

inline std::string_view trim(std::string_view s) {
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

// from_chars takes no leading '+'; one is allowed before a digit or '.', never before a '-'.
inline std::string_view drop_plus(std::string_view token) {
  if (token.size() > 1 && token.front() == '+' && token[1] != '-') token.remove_prefix(1);
  return token;
}

// Whole-token numeric parses: nullopt unless every character is consumed.
inline std::optional<double> parse_double(std::string_view token) {
  token = drop_plus(token);
  double value = 0;
  auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (ec != std::errc() || ptr != token.data() + token.size()) return std::nullopt;
  return value;
}

// `too_large`, when given, is set when the token is a whole integer that int64 cannot hold, so a
// caller can report "out of range" rather than "malformed".
inline std::optional<int64_t> parse_int(std::string_view token, bool* too_large = nullptr) {
  token = drop_plus(token);
  int64_t value = 0;
  auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  const bool whole = ptr == token.data() + token.size();
  if (too_large) *too_large = whole && ec == std::errc::result_out_of_range;
  if (ec != std::errc() || !whole) return std::nullopt;
  return value;
}

// The integer in [lo, hi] that a number read from a file stands for; nullopt when it is NaN,
// infinite, not integral or out of range. Use it instead of a cast: casting a double outside the
// integer type's range is undefined behaviour, so the range must be known before the cast.
inline std::optional<int64_t> to_integer(double value, int64_t lo, int64_t hi) {
  // -2^63 and 2^63 are exact doubles: the bound test itself rounds nothing.
  if (!(value >= -0x1p63 && value < 0x1p63) || value != std::trunc(value)) return std::nullopt;
  const auto integer = static_cast<int64_t>(value);
  if (integer < lo || integer > hi) return std::nullopt;
  return integer;
}

// Shortest round-trip text of a number, for messages and writers ("1e+300", not 300 digits).
inline std::string format_number(double value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  return std::string(buffer, result.ptr);
}

}  // namespace facemorph::text
