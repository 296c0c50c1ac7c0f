#include "codec/encoder/encode/frame_store.hpp"

#include "format/error.hpp"

#include "codec/encoder/encode/spill_bytes.hpp"

#include <string>

namespace facemorph {

namespace {

using spill::Reader;
using spill::Writer;

void write_mesh(Writer& w, const TriangleMesh& mesh) {
  w.array(mesh.positions);
  w.array(mesh.faces);
  w.array(mesh.uvs);
  w.array(mesh.uv_faces);
  w.text(mesh.texture.string());
  w.array(mesh.colours);
}

TriangleMesh read_mesh_bytes(Reader& r) {
  TriangleMesh mesh;
  mesh.positions = r.array<Vec3>();
  mesh.faces = r.array<Face>();
  mesh.uvs = r.array<Vec2>();
  mesh.uv_faces = r.array<Face>();
  mesh.texture = r.text();
  mesh.colours = r.array<Vec3>();
  return mesh;
}

// ConformalReport, RepairReport and FilledHole hold only numbers (and one string): written field by
// field, so a field added to them must be added here too (the round-trip test compares them all).
void write_conformal_report(Writer& w, const ConformalReport& c) {
  w.value(c.method);
  w.text(c.fallback_reason);
  for (int v : {c.iterations, c.factorizations, c.intrinsic_flips, c.split_chords, c.split_ears, c.split_obtuse_boundary, c.split_caps,
                c.caps_left, c.obtuse_boundary_left, c.flipped_triangles, c.untangled_vertices}) {
    w.value(v);
  }
  for (double v : {c.energy, c.energy_excess, c.seconds_prepare, c.seconds_initial, c.seconds_flow, c.seconds_finish}) w.value(v);
}

ConformalReport read_conformal_report(Reader& r) {
  ConformalReport c;
  c.method = r.value<ConformalMethod>();
  c.fallback_reason = r.text();
  for (int* v : {&c.iterations, &c.factorizations, &c.intrinsic_flips, &c.split_chords, &c.split_ears, &c.split_obtuse_boundary,
                 &c.split_caps, &c.caps_left, &c.obtuse_boundary_left, &c.flipped_triangles, &c.untangled_vertices}) {
    *v = r.value<int>();
  }
  for (double* v : {&c.energy, &c.energy_excess, &c.seconds_prepare, &c.seconds_initial, &c.seconds_flow, &c.seconds_finish})
    *v = r.value<double>();
  return c;
}

void write_repair_report(Writer& w, const RepairReport& report) {
  for (int v : {report.merged_vertices, report.dropped_degenerate_faces, report.split_faces, report.dropped_duplicate_faces,
                report.dropped_unreferenced_vertices, report.reoriented_faces, report.dropped_components, report.dropped_component_faces,
                report.non_manifold_edges, report.dropped_sheet_faces, report.dropped_sheets, report.split_vertices, report.added_vertices,
                report.rewired_faces, report.dropped_specks, report.dropped_speck_faces, report.faces_changed, report.vertices_changed}) {
    w.value(v);
  }
  w.value(report.largest_move);
  w.value(report.diagonal);
  w.value<uint64_t>(report.holes.size());
  for (const FilledHole& h : report.holes) {
    w.array(h.loop);
    for (int v : {h.first_vertex, h.vertex_count, h.first_face, h.face_count, h.folded_faces}) w.value(v);
    for (double v : {h.perimeter, h.area, h.min_angle_degrees, h.sharpest_hole_corner_degrees}) w.value(v);
  }
}

RepairReport read_repair_report(Reader& r) {
  RepairReport report;
  for (int* v :
       {&report.merged_vertices, &report.dropped_degenerate_faces, &report.split_faces, &report.dropped_duplicate_faces,
        &report.dropped_unreferenced_vertices, &report.reoriented_faces, &report.dropped_components, &report.dropped_component_faces,
        &report.non_manifold_edges, &report.dropped_sheet_faces, &report.dropped_sheets, &report.split_vertices, &report.added_vertices,
        &report.rewired_faces, &report.dropped_specks, &report.dropped_speck_faces, &report.faces_changed, &report.vertices_changed}) {
    *v = r.value<int>();
  }
  report.largest_move = r.value<double>();
  report.diagonal = r.value<double>();
  // At least a loop's length and nine numbers a hole.
  report.holes.resize(r.items(sizeof(uint64_t) + 5 * sizeof(int) + 4 * sizeof(double)));
  for (FilledHole& h : report.holes) {
    h.loop = r.array<int>();
    for (int* v : {&h.first_vertex, &h.vertex_count, &h.first_face, &h.face_count, &h.folded_faces}) *v = r.value<int>();
    for (double* v : {&h.perimeter, &h.area, &h.min_angle_degrees, &h.sharpest_hole_corner_degrees}) *v = r.value<double>();
  }
  return report;
}

}  // namespace

std::vector<char> FrameStore::serialize(const MappedFrame& frame) {
  Writer w;
  w.text(frame.name);
  // The prepared frame without its mesh (see put).
  w.array(frame.prepared.rim);
  w.array(frame.prepared.source_vertex);
  write_repair_report(w, frame.prepared.report);
  write_mesh(w, frame.map.surface);
  w.array(frame.map.disk);
  w.array(frame.map.rim);
  w.array(frame.map.source_vertex);
  w.value(frame.map.normalization.a);
  w.value(frame.map.normalization.theta);
  write_conformal_report(w, frame.map.report);
  w.value(frame.normalized);
  w.value(frame.found.has_value());
  if (frame.found) {
    const FaceOrientation& o = *frame.found;
    for (const Vec3& v : {o.nose_tip, o.up, o.facing, o.vertical}) w.value(v);
    for (double v : {o.facing_share, o.mirror_error, o.up_evidence}) w.value(v);
    w.value(o.up_from_hint);
    w.value(static_cast<uint8_t>(o.method));
    w.value(o.confidence);
  }
  w.array(frame.found_rim);
  w.value(frame.seconds_prepare);
  w.value(frame.seconds_map);
  return w.take();
}

MappedFrame FrameStore::deserialize(const char* bytes, size_t size) {
  Reader r(bytes, size, "frame store: a stored frame");
  MappedFrame frame;
  frame.name = r.text();
  frame.prepared.rim = r.array<int>();
  frame.prepared.source_vertex = r.array<int>();
  frame.prepared.report = read_repair_report(r);
  frame.map.surface = read_mesh_bytes(r);
  frame.map.disk = r.array<Vec2>();
  frame.map.rim = r.array<int>();
  frame.map.source_vertex = r.array<int>();
  frame.map.normalization.a = r.value<Complex>();
  frame.map.normalization.theta = r.value<double>();
  frame.map.report = read_conformal_report(r);
  frame.normalized = r.value<bool>();
  if (r.value<bool>()) {
    FaceOrientation o;
    for (Vec3* v : {&o.nose_tip, &o.up, &o.facing, &o.vertical}) *v = r.value<Vec3>();
    for (double* v : {&o.facing_share, &o.mirror_error, &o.up_evidence}) *v = r.value<double>();
    o.up_from_hint = r.value<bool>();
    o.method = static_cast<FaceFindingMethod>(r.value<uint8_t>());
    o.confidence = r.value<double>();
    frame.found = o;
  }
  frame.found_rim = r.array<Vec3>();
  frame.seconds_prepare = r.value<double>();
  frame.seconds_map = r.value<double>();
  if (!r.done()) throw Error(ErrorCode::kInternal, "frame store: a stored frame has bytes left over");
  return frame;
}

FrameStore::FrameStore(Mode mode)
    : mode_(mode),
      counter_(std::make_shared<Counter>()),
      items_(mode, "the frames' maps", "frame store: frame", &FrameStore::serialize, &FrameStore::deserialize, counter_) {}

FrameStore::~FrameStore() = default;

void FrameStore::reset(size_t count) {
  items_.reset(count);
  counter_->reset_peak();
}

void FrameStore::put(size_t i, MappedFrame&& frame) {
  const std::string name = frame.name;
  try {
    items_.put(i, std::move(frame));
  } catch (const Error& e) {
    // A full disk names the frame whose map could not be written.
    if (e.code() != ErrorCode::kIo) throw;
    throw Error(e.code(), name + ": " + e.what());
  }
}

}  // namespace facemorph
