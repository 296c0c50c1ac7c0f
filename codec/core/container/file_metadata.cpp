// What a file says about itself (file_metadata.hpp): names, the default pose steps, and a keyframe
// rounded as a file of a coding stores it.
#include "codec/core/container/file_metadata.hpp"

#include "codec/core/container/file_layout.hpp"
#include "codec/core/util/enum_names.hpp"
#include "format/error.hpp"

namespace facemorph {

using namespace file_layout;

namespace {

constexpr EnumName<TextureCoding> kTextureCodingNames[] = {{TextureCoding::kSequence, "sequence"}, {TextureCoding::kStills, "stills"}};

}  // namespace

const char* texture_coding_name(TextureCoding coding) { return name_of(kTextureCodingNames, coding); }

TextureCoding parse_texture_coding(const std::string& name) { return parse_name(kTextureCodingNames, name, "texture coding"); }

void round_to_field_steps(Keyframe& key, const FieldCoding& coding) {
  check_field_coding(coding);
  std::vector<std::vector<double>> arrays = keyframe_arrays(key);
  for (size_t a = 0; a < kKeyframeArrays; ++a) {
    for (double& v : arrays[a]) v = coding.steps[a] * field_code(v, coding.steps[a]);
  }
  assign_keyframe_arrays(key, std::move(arrays), key.fields.representation, key.fields.grid_n, key.fields.fixed_nodes);
  key.pose = pose_of(pose_codes(key.pose, coding), coding);
}

void set_default_pose_steps(FieldCoding& coding, const std::string& units) {
  constexpr double kRotationStep = 1e-5, kTranslationStepMetres = 1e-5;
  const double metres = units == "m" ? 1 : units == "cm" ? 1e-2 : units == "mm" ? 1e-3 : 0;
  if (metres == 0) throw Error(ErrorCode::kInvalidArgument, "units '" + units + "' (m, cm or mm)");
  coding.rotation_step = kRotationStep;
  coding.translation_step = kTranslationStepMetres / metres;
}

}  // namespace facemorph
