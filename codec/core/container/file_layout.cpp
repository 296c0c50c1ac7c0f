// What the readers and writers of a .fmv file's chunks share (file_layout.hpp): varints, finite
// numbers, the pose's codes, a keyframe's arrays and their codes.
#include "codec/core/container/file_layout.hpp"

#include "codec/core/grid/disk_grid.hpp"

#include <cmath>

namespace facemorph::file_layout {

using format::ByteReader;
using format::ByteWriter;

double read_finite(ByteReader& r, const char* what) {
  const double v = r.read<double>(what);
  if (!std::isfinite(v)) corrupt(r.source(), std::string(what) + " is not finite");
  return v;
}

std::vector<size_t> expected_lengths(int grid_n, Representation representation, size_t fixed, bool with_holes) {
  const DiskGridShape shape = disk_grid_shape(grid_n);
  const auto interior = static_cast<size_t>(shape.interior_count);
  const auto rim = static_cast<size_t>(shape.rim_count);
  const bool fields = representation != Representation::kXYZ;
  const bool tangential = representation == Representation::kHLT;
  const size_t holes = with_holes ? interior + rim : 0;
  return {fields ? interior : 0,
          fields ? interior : 0,
          tangential ? interior : 0,
          tangential ? interior : 0,
          fixed,
          fixed,
          fixed,
          fields ? 0 : interior,
          fields ? 0 : interior,
          fields ? 0 : interior,
          rim,
          rim,
          rim,
          holes};
}

std::vector<size_t> expected_lengths(const FileHeader& h) {
  return expected_lengths(h.shape.grid_n, h.shape.representation, h.fixed_nodes.size(), h.has_holes());
}

void write_varint(ByteWriter& w, int64_t value) {
  uint64_t zigzag = value >= 0 ? static_cast<uint64_t>(value) << 1 : (static_cast<uint64_t>(-(value + 1)) << 1) | 1;
  while (zigzag >= 0x80) {
    w.write(static_cast<uint8_t>(zigzag | 0x80));
    zigzag >>= 7;
  }
  w.write(static_cast<uint8_t>(zigzag));
}

int64_t read_varint(ByteReader& r, const char* what) {
  uint64_t zigzag = 0;
  for (int i = 0; i < kMaxVarintBytes; ++i) {
    const uint8_t byte = r.read<uint8_t>(what);
    zigzag |= static_cast<uint64_t>(byte & 0x7F) << (7 * i);
    if ((byte & 0x80) == 0) {
      const auto magnitude = static_cast<int64_t>(zigzag >> 1);  // below 2⁴¹
      return (zigzag & 1) != 0 ? -magnitude - 1 : magnitude;
    }
  }
  corrupt(r.source(), std::string(what) + " longer than " + std::to_string(kMaxVarintBytes) + " bytes");
}

PoseCodes pose_codes(const RigidPose& pose, const FieldCoding& coding) {
  const Vec3 rotation = rotation_log(pose.rotation);
  PoseCodes codes{};
  for (int k = 0; k < 3; ++k) {
    const double r = std::nearbyint(rotation[k] / coding.rotation_step), t = std::nearbyint(pose.translation[k] / coding.translation_step);
    if (!(std::abs(r) < static_cast<double>(kMaxPoseCode)) || !(std::abs(t) < static_cast<double>(kMaxPoseCode))) {
      throw Error(ErrorCode::kInvalidArgument,
                  "a pose more than 2^40 pose steps from the origin (translation " + std::to_string(pose.translation[k]) + ")");
    }
    if (std::abs(coding.rotation_step * r) > kMaxRotationComponent) {
      throw Error(ErrorCode::kInvalidArgument,
                  "a rotation step of " + std::to_string(coding.rotation_step) + " rad rounds a rotation vector beyond 4");
    }
    codes[static_cast<size_t>(k)] = static_cast<int64_t>(r);
    codes[static_cast<size_t>(3 + k)] = static_cast<int64_t>(t);
  }
  return codes;
}

RigidPose pose_of(const PoseCodes& codes, const FieldCoding& coding) {
  RigidPose pose;
  const auto c = [&](size_t i) { return static_cast<double>(codes[i]); };
  pose.rotation = rotation_exp(Vec3(coding.rotation_step * c(0), coding.rotation_step * c(1), coding.rotation_step * c(2)));
  pose.translation = Vec3(coding.translation_step * c(3), coding.translation_step * c(4), coding.translation_step * c(5));
  return pose;
}

std::vector<std::vector<double>> keyframe_arrays(const Keyframe& key) {
  std::vector<std::vector<double>> arrays = scalar_arrays(key.fields);
  arrays.push_back(key.hole_level);
  return arrays;
}

void assign_keyframe_arrays(Keyframe& key, std::vector<std::vector<double>> arrays, Representation representation, int grid_n,
                            std::vector<int32_t> fixed_nodes) {
  key.hole_level = std::move(arrays[kScalarArrayCount]);
  arrays.resize(kScalarArrayCount);
  key.fields = fields_from_scalar_arrays(representation, grid_n, std::move(fixed_nodes), arrays);
}

int32_t field_code(double value, double step) {
  const double code = std::nearbyint(value / step);
  if (!(std::abs(code) < static_cast<double>(kMaxFieldCode))) {
    throw Error(ErrorCode::kInvalidArgument,
                "a field value " + std::to_string(value) + " lies more than 2^30 steps of " + std::to_string(step) + " from 0");
  }
  return static_cast<int32_t>(code);
}

void check_field_coding(const FieldCoding& coding) {
  if (coding.steps.size() != kKeyframeArrays) throw Error(ErrorCode::kInvalidArgument, "field coding: one step per keyframe array needed");
  for (double step : coding.steps) {
    if (!(step > 0) || !std::isfinite(step))
      throw Error(ErrorCode::kInvalidArgument, "field coding: a step that is not finite and positive");
  }
  if (coding.intra_period < 1 || static_cast<uint32_t>(coding.intra_period) > kMaxIntraPeriod) {
    throw Error(ErrorCode::kInvalidArgument, "field coding: intra period outside [1, 2^20]");
  }
  if (!(coding.rotation_step > 0 && coding.translation_step > 0 && std::isfinite(coding.rotation_step) &&
        std::isfinite(coding.translation_step))) {
    throw Error(ErrorCode::kInvalidArgument, "field coding: pose steps that are not finite and positive (set_default_pose_steps)");
  }
}

}  // namespace facemorph::file_layout
