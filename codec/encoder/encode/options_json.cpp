// The encode options' one schema (options_json.hpp): options_fields lists each field once, with its
// key; a writer and a reader walk the same list.
#include "codec/encoder/encode/options_json.hpp"

#include "codec/encoder/encode/json_fields.hpp"

#include "format/error.hpp"

#include <nlohmann/json.hpp>

#include <functional>
#include <vector>

namespace facemorph {

namespace {

using Json = nlohmann::json;

// How deep the options may nest: a measure's are three levels (the sample's objects within it).
constexpr int kMaxOptionsDepth = 8;

// Builds the JSON object: each field under its key.
class OptionsWriter {
 public:
  template <typename T>
  void value(const char* key, const T& v) {
    top()[key] = v;
  }
  // An enumeration as its number (what the files have always held).
  template <typename E>
  void enumeration(const char* key, const E& v, E /*last*/) {
    top()[key] = static_cast<int>(v);
  }
  void representation(const char* key, const std::optional<Representation>& v) { top()[key] = v ? representation_name(*v) : "auto"; }
  void object(const char* key, const std::function<void()>& fields) {
    stack_.push_back(&top()[key]);
    top() = Json::object();
    fields();
    stack_.pop_back();
  }
  Json& top() { return *stack_.back(); }
  Json take() { return std::move(root_); }

 private:
  Json root_ = Json::object();
  std::vector<Json*> stack_{&root_};
};

// Reads each field from its key; kCorrupt naming the field where it is missing or not of its type.
class OptionsReader {
 public:
  explicit OptionsReader(const Json& root) : stack_{&root} {}
  void value(const char* key, bool& v) { v = json_fields::field<bool>(top(), key, what()); }
  void value(const char* key, int& v) { v = json_fields::integer_field(top(), key, what()); }
  void value(const char* key, double& v) { v = json_fields::field<double>(top(), key, what()); }
  template <typename E>
  void enumeration(const char* key, E& v, E last) {
    const int number = json_fields::integer_field(top(), key, what());
    if (number < 0 || number > static_cast<int>(last))
      json_fields::bad(what() + "'s \"" + key + "\" is no choice of its kind (" + std::to_string(number) + ")");
    v = static_cast<E>(number);
  }
  void representation(const char* key, std::optional<Representation>& v) {
    const auto name = json_fields::field<std::string>(top(), key, what());
    try {
      v = name == "auto" ? std::nullopt : std::optional(parse_representation(name));
    } catch (const Error&) {
      json_fields::bad(what() + "'s \"" + key + "\" is no representation ('" + name + "')");
    }
  }
  void object(const char* key, const std::function<void()>& fields) {
    const Json& inner = json_fields::field<Json>(top(), key, what());
    if (!inner.is_object()) json_fields::bad(what() + "'s \"" + key + "\" is not an object");
    stack_.push_back(&inner);
    path_.push_back(key);
    fields();
    path_.pop_back();
    stack_.pop_back();
  }

 private:
  const Json& top() const { return *stack_.back(); }
  std::string what() const {  // "the options (sample.conformal)"
    std::string path;
    for (const char* key : path_) {
      if (!path.empty()) path += '.';
      path += key;
    }
    return path.empty() ? std::string("the options") : "the options (" + path + ")";
  }
  std::vector<const Json*> stack_;
  std::vector<const char*> path_;
};

// The schema: each field once, with its key, in the order of the stages that depend on it. A
// writer and a reader both walk it (Fields: OptionsWriter or OptionsReader; Options: EncodeOptions,
// const for the writer).
template <typename Fields, typename Options>
void options_fields(Fields& f, Options& o, OptionsScope scope) {
  // kSample: what the map, register and sample stages depend on (a part file's).
  const auto sample = [&] {
    f.value("reference_frame", o.reference_frame);
    f.value("strict", o.strict);
    f.value("texture", o.texture);
    f.value("largest_component", o.largest_component);
    f.value("find_landmarks", o.find_landmarks);
    f.value("track_landmarks", o.track_landmarks);
    f.value("landmark_tolerance", o.landmark_tolerance);
    f.object("conformal", [&] {
      f.enumeration("method", o.conformal.method, ConformalMethod::kTutte);
      f.value("fallback", o.conformal.fallback);
      f.value("max_iterations", o.conformal.max_iterations);
      f.value("energy_tolerance", o.conformal.energy_tolerance);
    });
    auto& r = o.registration;
    f.object("registration", [&] {
      f.enumeration("method", r.method, RegistrationMethod::kFrame);
      f.enumeration("form", r.form, GmfForm::kPaperGrid);
      f.enumeration("moebius_start", r.moebius.start, MoebiusStart::kAlgebraic);
      f.value("smoothing", r.smoothing);
      f.value("paper_grid_n", r.paper_grid_n);
      f.value("boundary_spacing_degrees", r.boundary_spacing_degrees);
      f.value("fold_grid", r.fold_grid);
      f.value("min_area_ratio", r.min_area_ratio);
      f.value("smoothing_tries", r.smoothing_tries);
      f.value("max_substeps", r.max_substeps);
      f.value("allow_fallback", r.allow_fallback);
    });
    auto& d = o.density_equalising;
    f.object("density_equalising", [&] {
      f.value("strength", d.strength);
      f.value("step", d.step);
      f.value("max_steps", d.max_steps);
      f.value("tolerance", d.tolerance);
      f.value("radial", d.radial);
    });
  };
  if (scope == OptionsScope::kSample) {
    sample();
    return;
  }
  // kSegment: the sample stage's under "sample", and what the keyframes' planning and coding depend on.
  f.object("sample", sample);
  f.value("keyframes", o.keyframe_fraction);
  f.value("keyframe_error_bound", o.keyframe_error_bound);
  f.value("keyframe_p99_bound", o.keyframe_p99_bound);
  f.value("sparse_frame_interval", o.sparse_frame_interval);
  f.value("max_error", o.max_error);
  f.value("grid", o.grid);
  f.representation("representation", o.representation);
  f.enumeration("spline", o.spline, SplineKind::kLinear);
  auto& t = o.texture_coding;
  f.object("texture", [&] {
    f.value("size", o.texture_size);
    f.enumeration("codec", o.texture_codec, TextureCodec::kWebp);
    f.value("quality", o.texture_quality);
    f.value("share", o.share_textures);
    f.value("interpolation_share", t.interpolation_share);
    f.value("min_psnr", t.min_psnr);
    f.value("max_psnr", t.max_psnr);
    f.value("fallback", t.fallback_quality);
  });
  f.value("keep_holes_filled", o.keep_holes_filled);
  auto& p = o.field_precision;
  f.object("fields", [&] {
    f.value("predicted", o.predicted_fields);
    f.value("auto_error", o.auto_field_error);
    f.value("target_error", p.target_error);
    f.value("intra_period", p.intra_period);
    f.value("noise_shaping", p.noise_shaping);
    f.value("inter_dead_zone", p.inter_dead_zone);
  });
  f.object("keyframe_fit", [&] {
    f.value("on", o.keyframe_fit);
    f.value("weight", o.keyframe_fit_weight);
    f.value("noise", o.keyframe_fit_noise);
  });
}

}  // namespace

std::string write_options(const EncodeOptions& options, OptionsScope scope) {
  OptionsWriter writer;
  options_fields(writer, options, scope);
  return writer.take().dump();
}

EncodeOptions read_options(std::string_view text, OptionsScope scope, EncodeOptions options) {
  const Json doc = json_fields::parse_object(text, kMaxOptionsDepth, "the options");
  OptionsReader reader(doc);
  options_fields(reader, options, scope);
  return options;
}

bool same_options(std::string_view stored, const EncodeOptions& options, OptionsScope scope) {
  return same_options(stored, write_options(options, scope));
}

bool same_options(std::string_view stored, std::string_view written) {
  try {
    // As values: a key the schema lacks (a later encoder's option) is a difference, as is one missing.
    return json_fields::parse_object(stored, kMaxOptionsDepth, "the options") == Json::parse(written);
  } catch (const Error&) {
    return false;  // not JSON, or nested too deep: not these options
  }
}

}  // namespace facemorph
