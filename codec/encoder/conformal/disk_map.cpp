// The Riemann conformal map: preconditioning, linear start, QIEM on the double cover, projection.
#include "codec/encoder/conformal/conformal.hpp"

#include "codec/core/geometry/differential.hpp"
#include "codec/core/util/enum_names.hpp"
#include "codec/meshkit/geometry/surface_measures.hpp"
#include "codec/meshkit/mesh/topology.hpp"
#include "format/error.hpp"

#include "codec/core/util/elapsed.hpp"
#include "codec/encoder/conformal/double_cover.hpp"
#include "codec/encoder/conformal/linear_map.hpp"
#include "codec/encoder/conformal/qiem.hpp"
#include "codec/encoder/conformal/untangle.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>
#include <utility>

namespace facemorph {

namespace {

constexpr EnumName<ConformalMethod> kConformalMethodNames[] = {
    {ConformalMethod::kQiem, "qiem"}, {ConformalMethod::kLinear, "linear"}, {ConformalMethod::kTutte, "tutte"}};

}  // namespace

const char* conformal_method_name(ConformalMethod method) { return name_of(kConformalMethodNames, method); }

ConformalMethod parse_conformal_method(const std::string& name) { return parse_name(kConformalMethodNames, name, "conformal method"); }

namespace {

DiskMap unmapped(const TriangleMesh& input) {
  DiskMap map;
  map.surface = input;
  map.source_vertex.resize(input.positions.size());
  for (size_t i = 0; i < map.source_vertex.size(); ++i) map.source_vertex[i] = static_cast<int>(i);
  return map;
}

// The last resort (spec/method.md §3.6): Tutte's map of the disk as given, no preconditioning.
DiskMap tutte_map(const TriangleMesh& input, TopologyCache& topologies) {
  auto start = std::chrono::steady_clock::now();
  DiskMap map = unmapped(input);
  map.rim = topologies.of(map.surface).boundary_loops()[0];
  map.disk = tutte_disk_map(map.surface, map.rim);
  for (int v : map.rim) map.disk[static_cast<size_t>(v)].normalize();
  map.report.method = ConformalMethod::kTutte;
  map.report.seconds_initial = seconds_since(start);
  start = std::chrono::steady_clock::now();
  finish_disk_map(map, {});
  map.report.seconds_finish = seconds_since(start);
  return map;
}

// Preconditioning, the linear map, and QIEM from it (unless options.method is kLinear); QIEM's
// failures fall back to the linear map when options.fallback allows.
DiskMap preconditioned_map(const TriangleMesh& input, const ConformalOptions& options, TopologyCache& topologies) {
  auto start = std::chrono::steady_clock::now();
  DiskMap map = unmapped(input);
  ConformalReport& report = map.report;
  const DiskPreconditioning pre = precondition_disk(map.surface, map.source_vertex, topologies);
  report.split_chords = pre.split_chords;
  report.split_ears = pre.split_ears;
  report.split_obtuse_boundary = pre.split_obtuse_boundary;
  report.split_caps = pre.split_caps;
  report.caps_left = pre.caps_left;
  report.obtuse_boundary_left = pre.obtuse_boundary_left;
  map.rim = topologies.of(map.surface).boundary_loops()[0];
  report.seconds_prepare = seconds_since(start);

  start = std::chrono::steady_clock::now();
  const IntrinsicMesh intrinsic = intrinsic_delaunay(map.surface);
  report.intrinsic_flips = intrinsic.flips;
  map.disk = linear_disk_map(map.surface, intrinsic, map.rim);
  report.method = ConformalMethod::kLinear;
  std::vector<Vec2> linear = options.method == ConformalMethod::kQiem && options.fallback ? map.disk : std::vector<Vec2>();
  report.seconds_initial = seconds_since(start);

  if (options.method == ConformalMethod::kQiem) {
    start = std::chrono::steady_clock::now();
    try {
      // The disk is already intrinsic Delaunay; glued, only its boundary edges (now interior, with
      // equal opposite angles) can still need a flip.
      std::vector<uint8_t> on_boundary(static_cast<size_t>(map.surface.vertex_count()), 0);
      for (int v : map.rim) on_boundary[static_cast<size_t>(v)] = 1;
      const DoubleCover cover = build_double_cover(intrinsic.faces, intrinsic.lengths, on_boundary);
      std::vector<Face> faces = cover.faces;
      std::vector<CornerValues> lengths = cover.lengths;
      report.intrinsic_flips += flip_to_intrinsic_delaunay(faces, lengths);
      const SparseMatrix K = laplacian_from_cotangents(faces, corner_cotangents_from_lengths(lengths), cover.vertex_count());
      Eigen::VectorXd areas = Eigen::VectorXd::Zero(cover.vertex_count());
      for (size_t f = 0; f < faces.size(); ++f) {
        const auto& l = lengths[f];
        const double s = 0.5 * (l[0] + l[1] + l[2]);
        const double area = std::sqrt(std::max(s * (s - l[0]) * (s - l[1]) * (s - l[2]), 0.0));
        for (int32_t v : faces[f]) areas[v] += area / 3;
      }
      const FlowResult flow = spherical_flow(K, areas, cover, initial_sphere_map(map.disk, cover), options);
      report.iterations = flow.iterations;
      report.factorizations = flow.factorizations;
      report.energy = flow.energy;
      // Image area: the spherical triangles' flat areas approach 4π from below as the map refines.
      double image_area = 0;
      for (const Face& f : faces) {
        const Eigen::Vector3d a = flow.phi.row(f[0]), b = flow.phi.row(f[1]), c = flow.phi.row(f[2]);
        image_area += triangle_area(a, b, c);
      }
      report.energy_excess = flow.energy - image_area;
      // Stereographic projection of copy 1 (southern hemisphere) from the north pole.
      std::vector<Vec2> w(map.disk.size());
      for (int i = 0; i < cover.disk_vertices; ++i) {
        const double denominator = 1.0 - flow.phi(i, 2);
        w[static_cast<size_t>(i)] = Vec2(flow.phi(i, 0), flow.phi(i, 1)) / denominator;
      }
      for (int v : map.rim) w[static_cast<size_t>(v)].normalize();  // exactly on the circle
      map.disk = std::move(w);
      report.method = ConformalMethod::kQiem;
    } catch (const Error& e) {
      if (!options.fallback) throw;
      report.fallback_reason = e.what();
    }
    report.seconds_flow = seconds_since(start);
  }

  start = std::chrono::steady_clock::now();
  // QIEM's disk falls back to the linear map where it cannot be untangled.
  const bool qiem = report.method == ConformalMethod::kQiem;
  finish_disk_map(map, qiem ? std::move(linear) : std::vector<Vec2>());
  report.seconds_finish = seconds_since(start);
  return map;
}

}  // namespace

DiskMap conformal_disk_map(const TriangleMesh& input, const ConformalOptions& options) {
  // One topology a mesh: the check's is preconditioning's first round's, and its last round's gives
  // the rim (TopologyCache rebuilds only after a split).
  TopologyCache topologies;
  {
    const MeshTopology& topology = topologies.of(input);
    if (!topology.is_manifold() || topology.boundary_loops().size() != 1 || topology.euler_characteristic() != 1) {
      throw Error(ErrorCode::kNotADisk, "the conformal map needs a disk (one boundary loop, Euler characteristic 1); got " +
                                            std::to_string(topology.boundary_loops().size()) + " loops, Euler characteristic " +
                                            std::to_string(topology.euler_characteristic()));
    }
  }
  if (options.method == ConformalMethod::kTutte) return tutte_map(input, topologies);
  try {
    return preconditioned_map(input, options, topologies);
  } catch (const Error& e) {
    // Whatever stopped the preconditioned maps (a solver, the intrinsic flips, untangling the
    // linear map), Tutte's map needs none of it.
    if (!options.fallback) throw;
    DiskMap map = tutte_map(input, topologies);
    map.report.fallback_reason = e.what();
    return map;
  }
}

}  // namespace facemorph
