#include "codec/encoder/encode/keyframe_store.hpp"

#include "format/error.hpp"

#include "codec/encoder/encode/spill_bytes.hpp"

#include <string>

namespace facemorph {

namespace {

using spill::Reader;
using spill::Writer;

void write_item(Writer& w, const std::vector<Vec3>& surface) { w.array(surface); }

void read_item(Reader& r, std::vector<Vec3>& surface) { surface = r.array<Vec3>(); }

// Field by field: a field added to GridFields must be added here too (the round-trip test compares
// them all).
void write_item(Writer& w, const GridFields& f) {
  w.value(f.representation);
  w.value(f.grid_n);
  w.array(f.mean_curvature);
  w.array(f.log_conformal_factor);
  w.array(f.tangential_u);
  w.array(f.tangential_v);
  w.array(f.fixed_nodes);
  w.array(f.fixed_laplacian);
  w.array(f.positions);
  w.array(f.rim);
}

void read_item(Reader& r, GridFields& f) {
  f.representation = r.value<Representation>();
  f.grid_n = r.value<int>();
  f.mean_curvature = r.array<double>();
  f.log_conformal_factor = r.array<double>();
  f.tangential_u = r.array<double>();
  f.tangential_v = r.array<double>();
  f.fixed_nodes = r.array<int32_t>();
  f.fixed_laplacian = r.array<Vec3>();
  f.positions = r.array<Vec3>();
  f.rim = r.array<Vec3>();
}

void write_item(Writer& w, const std::vector<double>& values) { w.array(values); }

void read_item(Reader& r, std::vector<double>& values) { values = r.array<double>(); }

void write_item(Writer& w, const Image& image) {
  w.value(image.width);
  w.value(image.height);
  w.value(image.channels);
  w.array(image.pixels);
}

void read_item(Reader& r, Image& image) {
  image.width = r.value<int>();
  image.height = r.value<int>();
  image.channels = r.value<int>();
  image.pixels = r.array<uint8_t>();
}

const char* kind_name(const std::vector<Vec3>*) { return "the keyframes' surfaces"; }
const char* kind_name(const GridFields*) { return "the keyframes' fields"; }
const char* kind_name(const std::vector<double>*) { return "the keyframes' hole levels"; }
const char* kind_name(const Image*) { return "the keyframes' textures"; }

}  // namespace

template <typename T>
KeyframeStore<T>::KeyframeStore(Mode mode, std::shared_ptr<ResidentCount> count)
    : count_(count ? std::move(count) : std::make_shared<ResidentCount>()),
      items_(mode, kind_name(static_cast<const T*>(nullptr)), "keyframe store: keyframe", &KeyframeStore<T>::serialize,
             &KeyframeStore<T>::deserialize, count_) {}

template <typename T>
std::vector<char> KeyframeStore<T>::serialize(const T& item) {
  Writer w;
  write_item(w, item);
  return w.take();
}

template <typename T>
T KeyframeStore<T>::deserialize(const char* bytes, size_t size) {
  const std::string what = std::string("keyframe store: one of ") + kind_name(static_cast<const T*>(nullptr));
  Reader r(bytes, size, what.c_str());
  T item;
  read_item(r, item);
  if (!r.done()) throw Error(ErrorCode::kInternal, what + " has bytes left over");
  return item;
}

template class KeyframeStore<std::vector<Vec3>>;
template class KeyframeStore<GridFields>;
template class KeyframeStore<std::vector<double>>;
template class KeyframeStore<Image>;

}  // namespace facemorph
