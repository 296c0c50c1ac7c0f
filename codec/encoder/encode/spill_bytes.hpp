// The byte form of what the encoder spills (frame_store.cpp, keyframe_store.cpp): numbers as their
// bytes, arrays with their length first. Private to the encoder.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/encoder/conformal/moebius.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

namespace facemorph::spill {

// Vectors of plain numbers are written as their bytes: the file lives only as long as the process,
// on the machine that wrote it, and a map read back must be the very same doubles (the encode's
// output must not depend on whether its frames were spilled).
static_assert(sizeof(Vec2) == 2 * sizeof(double) && sizeof(Vec3) == 3 * sizeof(double) && sizeof(Face) == 3 * sizeof(int32_t));
static_assert(sizeof(Complex) == 2 * sizeof(double) && sizeof(bool) == 1);
static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float) && sizeof(Eigen::Matrix2d) == 4 * sizeof(double) &&
              sizeof(Eigen::Matrix3d) == 9 * sizeof(double));
template <typename T>
constexpr bool kPlain =
    std::is_trivially_copyable_v<T> || std::is_same_v<T, Vec2> || std::is_same_v<T, Vec3> || std::is_same_v<T, Complex> ||
    std::is_same_v<T, Eigen::Vector3f> || std::is_same_v<T, Eigen::Matrix2d> || std::is_same_v<T, Eigen::Matrix3d>;

class Writer {
 public:
  template <typename T>
  void value(const T& v) {
    static_assert(kPlain<T>);
    bytes(&v, sizeof v);
  }
  void text(const std::string& s) {
    value<uint64_t>(s.size());
    bytes(s.data(), s.size());
  }
  template <typename T>
  void array(const std::vector<T>& v) {
    static_assert(kPlain<T>);
    value<uint64_t>(v.size());
    bytes(v.data(), v.size() * sizeof(T));
  }
  std::vector<char> take() { return std::move(out_); }

 private:
  void bytes(const void* data, size_t size) {
    const auto* p = static_cast<const char*>(data);
    out_.insert(out_.end(), p, p + size);
  }
  std::vector<char> out_;
};

class Reader {
 public:
  // `what` names the record in errors ("frame store: a stored frame").
  Reader(const char* data, size_t size, const char* what) : p_(data), end_(data + size), what_(what) {}
  template <typename T>
  T value() {
    static_assert(kPlain<T>);
    if constexpr (std::is_same_v<T, bool>) {
      // A byte that is neither 0 nor 1 is no bool (loading it as one is undefined): a record read
      // from a file may hold any byte there.
      uint8_t byte = 0;
      bytes(&byte, 1);
      if (byte > 1)
        throw Error(ErrorCode::kInternal, std::string(what_) + " holds " + std::to_string(byte) + " where a truth value belongs");
      return byte == 1;
    } else {
      T v;
      bytes(&v, sizeof v);
      return v;
    }
  }
  std::string text() {
    std::string s(count(1), '\0');
    bytes(s.data(), s.size());
    return s;
  }
  template <typename T>
  std::vector<T> array() {
    std::vector<T> v(count(sizeof(T)));
    bytes(v.data(), v.size() * sizeof(T));
    return v;
  }
  bool done() const { return p_ == end_; }
  // A count of items to come, each at least `item_bytes` long: checked against the bytes left
  // before the caller allocates for them (a record read from a file is untrusted).
  size_t items(size_t item_bytes) { return count(item_bytes); }

 private:
  size_t count(size_t item) {
    const auto n = value<uint64_t>();
    if (n > static_cast<uint64_t>(end_ - p_) / item) throw Error(ErrorCode::kInternal, std::string(what_) + " is cut short");
    return static_cast<size_t>(n);
  }
  void bytes(void* data, size_t size) {
    if (size > static_cast<size_t>(end_ - p_)) throw Error(ErrorCode::kInternal, std::string(what_) + " is cut short");
    if (size == 0) return;  // an empty array's data() may be null, which memcpy must not be given
    std::memcpy(data, p_, size);
    p_ += size;
  }
  const char* p_;
  const char* end_;
  const char* what_;
};

// Whether every vector of `values` is finite: what a record read from a file (a part file, spec/
// part-file.md) is checked for before its numbers are used (part_file.cpp, registration_store.cpp).
template <typename V>
bool all_finite(const std::vector<V>& values) {
  return std::all_of(values.begin(), values.end(), [](const V& v) { return v.allFinite(); });
}

}  // namespace facemorph::spill
