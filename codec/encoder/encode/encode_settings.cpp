#include "codec/encoder/encode/encode_settings.hpp"

#include "codec/encoder/encode/texture_quality.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>

namespace facemorph {

namespace {

using Json = nlohmann::json;

Json dropped_json(const EncodeReport& report) {
  Json list = Json::array();
  for (const DroppedFrame& d : report.dropped)
    list.push_back({{"frame", d.index}, {"name", d.name}, {"time", d.time}, {"reason", d.reason}});
  return list;
}

Json conformal_fallbacks_json(const EncodeReport& report) {
  Json list = Json::array();
  for (const EncodedFrameReport& f : report.frames) {
    if (!f.conformal_fallback_reason.empty()) {
      list.push_back({{"name", f.name},
                      {"time", f.time},
                      {"method", conformal_method_name(f.conformal_method)},
                      {"reason", f.conformal_fallback_reason}});
    }
  }
  return list;
}

// Every frame's repairs (spec/method.md §2.1): the totals over the frames, and the first frames'
// own lines (a long capture repairs every frame alike; the header's settings stay small).
Json repairs_json(const EncodeReport& report) {
  int frames = 0, faces = 0, vertices = 0;
  double move = 0, relative = 0;
  Json listed = Json::array();
  for (const EncodedFrameReport& f : report.frames) {
    const RepairTotals& t = f.repair_totals;
    if (f.repair == "valid as captured") continue;
    ++frames;
    faces += t.faces_changed;
    vertices += t.vertices_changed;
    move = std::max(move, t.largest_move);
    if (t.diagonal > 0) relative = std::max(relative, t.largest_move / t.diagonal);
    if (listed.size() < kRepairedFramesListed) listed.push_back({{"name", f.name}, {"repair", f.repair}});
  }
  return {{"frames_repaired", frames},
          {"faces_changed", faces},
          {"vertices_changed", vertices},
          {"largest_move", move},
          {"largest_move_of_diagonal", relative},
          {"frames", listed}};
}

Json settings_json(const EncodeOptions& o, const EncodeReport& report) {
  return {
      {"keyframes", o.max_error > 0 ? Json(nullptr) : Json(o.keyframe_fraction)},
      {"max_error", o.max_error > 0 ? Json(o.max_error) : Json(nullptr)},
      {"grid", o.grid > 0 ? Json(o.grid) : Json("auto")},
      {"grid_chosen", report.grid},
      {"representation", o.representation ? representation_name(*o.representation) : "auto"},
      {"representation_chosen", representation_name(report.representation)},
      {"frames_without_interior_landmarks", report.frames_without_interior_landmarks},
      {"representation_blend", report.blend.trials > 0 ? Json{{"frames", report.blend.trials},
                                                              {"fields_error", report.blend.fields_error},
                                                              {"positions_error", report.blend.positions_error},
                                                              {"fields_not_converged", report.blend.not_converged}}
                                                       : Json(nullptr)},
      {"registration", registration_method_name(o.registration.method)},
      {"spline", spline_kind_name(o.spline)},
      // Whether the file's residual frames took keyframes' places (residuals_pay): where they did
      // not, the settings and the file are those of an encode without them, byte for byte.
      {"residual_frames", o.residual_frames && report.residual_fit.keyframes_saved > 0},
      {"patch_bound", o.patch_bound},
      {"texture", o.texture ? (o.texture_size > 0 ? Json(o.texture_size) : Json("auto")) : Json(0)},
      {"texture_chosen", report.texture_size},
      {"texture_codec", texture_codec_name(o.texture_codec)},
      {"texture_quality", o.texture_quality == kAutoTextureQuality ? Json("auto") : Json(o.texture_quality)},
      {"texture_qualities_chosen", report.texture_qualities},
      {"texture_sharing", o.share_textures},
      {"sparse_frame_interval", o.sparse_frame_interval},
      {"keyframes_every_frame_sparse", report.sparse},
      {"texture_shared_with", report.texture_shared_with},
      {"keep_holes_filled", o.keep_holes_filled},
      {"largest_component", o.largest_component},
      {"reference_frame", o.reference_frame},
      {"density_equalising", o.density_equalising.strength},
      // The radial reparametrisation of a whole head (spec/method.md §7.11): asked ("auto" or a
      // strength), used, and the disk radius holding half the surface before and after.
      {"radial_equalising",
       {{"asked", o.density_equalising.radial == kAutoRadial ? Json("auto") : Json(o.density_equalising.radial)},
        {"strength", report.radial_equalising},
        {"half_area_radius", report.density_equalising.half_area_radius_before},
        {"half_area_radius_after", report.radial_equalising > 0 ? Json(report.density_equalising.half_area_radius_after) : Json(nullptr)}}},
      {"keyframe_fit", o.keyframe_fit},
      {"field_error", o.predicted_fields ? Json(report.field_precision.target_error) : Json(nullptr)},
      {"field_error_auto", o.predicted_fields && o.auto_field_error},
      {"intra_period", o.field_precision.intra_period == kAutoIntraPeriod ? Json("auto") : Json(o.field_precision.intra_period)},
      {"intra_period_chosen", report.field_coding.predicted() ? Json(report.field_coding.intra_period) : Json(nullptr)},
      {"field_rounding", o.field_precision.noise_shaping ? "shaped" : "nearest"},
      {"inter_dead_zone", o.field_precision.inter_dead_zone == kAutoDeadZone ? Json("auto") : Json(o.field_precision.inter_dead_zone)},
      {"inter_dead_zone_chosen", report.field_coding.predicted() ? Json(report.field_precision.inter_dead_zone) : Json(nullptr)},
      {"strict", o.strict},
      {"landmarks_found",
       {{"orientation_frames", report.orientation_found},
        {"rim_markers", report.rim_markers_found},
        {"weakest_up_evidence", report.orientation_found > 0 ? Json(report.weakest_up_evidence) : Json(nullptr)}}},
      // How the frames' orientation was found (find_face) and the least sure finding, in [0, 1].
      {"face_orientation", report.orientation_found > 0 ? Json{{"method", report.main_orientation_method()},
                                                               {"confidence", report.lowest_face_confidence},
                                                               {"frames",
                                                                {{"whole surface", report.orientation_methods[0]},
                                                                 {"texture", report.orientation_methods[1]},
                                                                 {"face region", report.orientation_methods[2]}}}}
                                                        : Json(nullptr)},
      {"landmarks_tracked",
       {{"frames", report.tracked_frames},
        {"grid_points", report.tracking_grid_points},
        {"points_mean", report.tracked_points_mean},
        {"points_fewest", report.tracked_points_fewest},
        {"round_trip_median", report.tracked_round_trip_median},
        {"round_trip_p90", report.tracked_round_trip_p90}}},
      {"reference_frame_chosen", report.reference_frame},
      {"dropped_frames", dropped_json(report)},
      {"conformal_fallbacks", conformal_fallbacks_json(report)},
      {"repairs", repairs_json(report)},
      {"warnings", report.warnings}};
}
}  // namespace

std::string encode_settings_json(const EncodeOptions& options, const EncodeReport& report) {
  Json settings = settings_json(options, report);
  // Only where it happened: every other file's settings stay as they were, byte for byte.
  if (!report.representation_fallback.empty()) settings["representation_fallback"] = report.representation_fallback;
  // The density-equalised disk kept by bytes at equal error (density_candidate.hpp): its strength.
  if (report.density_candidate.kept) settings["density_equalising_chosen"] = report.density_candidate.strength;
  return settings.dump();
}

}  // namespace facemorph
