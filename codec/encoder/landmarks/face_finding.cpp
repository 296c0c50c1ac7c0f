// Finding the face in a scan that holds more than a face (spec/method.md §7.14): the whole surface's
// mirror plane, then a face detected in rendered views of the textured surface, then the mirror
// plane of the region around the most protruding point.
#include "codec/encoder/landmarks/face_facing.hpp"
#include "codec/encoder/landmarks/face_orientation.hpp"

#include "codec/core/util/enum_names.hpp"

#include "codec/core/geometry/elementary.hpp"
#include "codec/encoder/imageio/image_io.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/geometry/surface_measures.hpp"
#include "codec/meshkit/mesh/topology.hpp"
#include "codec/meshkit/render/render.hpp"
#include "format/error.hpp"

#include <opencv2/imgproc.hpp>
#include <opencv2/objdetect.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

namespace facemorph {
namespace {

// Pixels per side of each rendered view: a face a fifth of a scan's width is ~60 px, twice the
// cascade's 24 px window.
constexpr int kViewSize = 320;
constexpr int kMinFacePixels = 28;
// The cascade's neighbour count at which a detection is taken as certain (fmsynth's faces read
// 11-19, a random texture's false detections 1-3); below kMinNeighbours none is taken.
constexpr int kConfidentNeighbours = 12;
constexpr int kMinNeighbours = 4;
// Where in the cascade's box the face's parts lie (fractions of its side, from its top-left): the
// box runs from the brows to below the mouth.
constexpr double kBoxCentreY = 0.58, kBoxEyesY = 0.38, kBoxChinY = 0.9;
// The region read as the face: the detected box grown by this factor about its centre (the box
// crops the forehead and chin).
constexpr double kRegionGrowth = 1.3;
// A texture's up and the region's geometric up must agree within 60° for the geometry to confirm.
constexpr double kMinAgreementCosine = 0.5;
// The face regions tried without a texture: balls about the most protruding point, as shares of the
// scan's diagonal, largest first (a face is a third to a sixth of a head-and-shoulders scan).
constexpr std::array<double, 3> kRegionReaches = {0.19, 0.15, 0.12};
// Below this share of its area in its mean normal a surface faces no one way (a whole head):
// find_face_orientation's own bound.
constexpr double kWholeHeadFacingShare = 0.25;
constexpr double kWholeHeadSure = 0.5;  // mirror error under 1.5% of the diagonal
// Around a whole head without holes, the directions whose regions a coarse first pass ranks best,
// read in full at every reach.
constexpr size_t kRefinedDirections = 3;
// A whole-surface finding at least this sure (mirror error under 1% of the diagonal) is taken as
// it is; a less sure one competes with the texture's and the face region's, the surest winning (a
// scan's hair and shoulders can make a slanted plane the best one, and up then reads wrong).
constexpr double kSureConfidence = 2.0 / 3;

const std::filesystem::path kCascadeFile = FACEMORPH_FACE_CASCADE;

// How far up the midline a region's `up` point is placed (find_face_orientation's up_scale): from the
// diameter of the largest region tried, a share of the whole scan's diagonal. The region's own
// diagonal follows which region won and its cut, and varied the point from 11 to 17 mm from the tip
// across 12 frames of fmsynth --head --holes; the registration then stretched the face between the
// frames by that difference.
double region_up_scale(const TriangleMesh& mesh) { return 2 * kRegionReaches.front() * bounding_box_diagonal(mesh.positions); }

// find_face_orientation's reason, without the frame's name and the advice (find_face names them once).
std::string reason_of(const Error& e, const std::string& name) {
  std::string what = e.what();
  const std::string head = name + ": no face orientation found: ", tail = " (give the capture its landmarks nose_tip and nose_bridge)";
  if (what.rfind(head, 0) == 0) what.erase(0, head.size());
  if (what.size() >= tail.size() && what.compare(what.size() - tail.size(), tail.size(), tail) == 0) what.erase(what.size() - tail.size());
  return what;
}

double geometry_confidence(const FaceOrientation& o) { return std::clamp(1 - o.mirror_error / kMaxFaceMirrorError, 0.0, 1.0); }

// A face's nose falls away steeply from its tip (FaceOrientation::nose_prominence, on its steeper
// side: 0.81-0.90 on fmsynth's faces, 0.82-1.05 on Medusa's 232 frames, 0.74 on ICT's, 0.69-1.05 in
// the head-and-shoulders scans' face regions, 0.39 and up in ICT's whole head's); a dome's top,
// whose mirror plane is as good as a face's and which a region beside hair can read up from, barely
// falls (0.06 in such a region, up to 0.2 on the whole scan, the hair included). Below
// kMinNoseProminence the geometry shows no face, however good its mirror plane.
constexpr double kMinNoseProminence = 0.3;
// In [0, 1]: how clearly the surface has a nose, 1 from twice kMinNoseProminence.
double face_shape_confidence(const FaceOrientation& o) { return std::clamp(o.nose_prominence / (2 * kMinNoseProminence), 0.0, 1.0); }
bool geometry_shows_face(const FaceOrientation& o) { return o.nose_prominence >= kMinNoseProminence; }

std::string percent_text(double share) {
  char text[32];
  std::snprintf(text, sizeof text, "%.2g%%", 100 * share);
  return text;
}

// Why a geometric finding shows no face, with what was measured.
std::string no_face_shape(const FaceOrientation& o) {
  char text[320];
  std::snprintf(text, sizeof text,
                "%s: a mirror plane (%s of the diagonal off) but no nose: the surface falls %.2g a unit from its most protruding point, "
                "where a nose falls at least %.2g: a dome, not a face",
                face_finding_method_name(o.method), percent_text(o.mirror_error).c_str(), o.nose_prominence, kMinNoseProminence);
  return text;
}

Vec3 area_weighted_normal(const TriangleMesh& mesh) {
  Vec3 sum = Vec3::Zero();
  for (const Face& f : mesh.faces) {
    const Vec3 &a = mesh.positions[static_cast<size_t>(f[0])], &b = mesh.positions[static_cast<size_t>(f[1])],
               &c = mesh.positions[static_cast<size_t>(f[2])];
    sum += (b - a).cross(c - a);
  }
  return sum;
}

// ---- The texture: a face detected in rendered views ----

struct Detection {
  Eigen::Matrix3d turn;  // the view: mesh points turned so the camera looks down -z, image up +y
  cv::Rect box;
  int neighbours = 0;
};

class TextureFaceFinder {
 public:
  TextureFaceFinder(const TriangleMesh& mesh, const Image* texture) : mesh_(mesh) {
    if (mesh.has_uvs() && texture && !texture->empty()) {
      colour_ = texture_shader(mesh, *texture);
    } else if (mesh.has_colours()) {
      colour_ = [&mesh](int f, const Vec3& bary) {
        Vec3 c = Vec3::Zero();
        for (int k = 0; k < 3; ++k) c += bary[k] * mesh.colours[static_cast<size_t>(mesh.faces[static_cast<size_t>(f)][k])];
        return std::array<double, 3>{255 * c.x(), 255 * c.y(), 255 * c.z()};
      };
    }
  }

  // Why no texture can be read; empty when one can.
  std::string unavailable() const {
    if (!colour_) return "the surface has no texture";
    if (!std::filesystem::exists(kCascadeFile))
      return "OpenCV's face cascade " + kCascadeFile.string() + " is not installed (Debian: opencv-data)";
    return {};
  }

  // The detection with the most neighbours over views from the mean normal and the six axes, each
  // turned by 0, 90, 180 and 270° about the view (the cascade finds upright faces only).
  std::optional<Detection> detect() const {
    cv::CascadeClassifier cascade(kCascadeFile.string());
    if (cascade.empty()) return std::nullopt;
    std::vector<Vec3> directions = {Vec3::UnitZ(), -Vec3::UnitZ(), Vec3::UnitX(), -Vec3::UnitX(), Vec3::UnitY(), -Vec3::UnitY()};
    const Vec3 mean = area_weighted_normal(mesh_);
    if (mean.norm() > 0) directions.insert(directions.begin(), mean.normalized());
    std::optional<Detection> best;
    for (const Vec3& towards : directions) {
      const Eigen::Matrix3d facing = Eigen::Quaterniond::FromTwoVectors(towards, Vec3::UnitZ()).toRotationMatrix();
      for (int roll = 0; roll < 4; ++roll) {
        const Eigen::Matrix3d turn = Eigen::AngleAxisd(roll * std::numbers::pi / 2, Vec3::UnitZ()).toRotationMatrix() * facing;
        const Image view = render_view(turn, colour_);
        cv::Mat rgb(view.height, view.width, CV_8UC3, const_cast<uint8_t*>(view.pixels.data())), gray;
        cv::cvtColor(rgb, gray, cv::COLOR_RGB2GRAY);
        cv::equalizeHist(gray, gray);
        std::vector<cv::Rect> boxes;
        std::vector<int> neighbours;
        cascade.detectMultiScale(gray, boxes, neighbours, 1.1, kMinNeighbours, 0, cv::Size(kMinFacePixels, kMinFacePixels));
        for (size_t i = 0; i < boxes.size(); ++i) {
          if (!best || neighbours[i] > best->neighbours) best = Detection{turn, boxes[i], neighbours[i]};
        }
      }
    }
    return best;
  }

  // The faces seen in `d`'s box grown by kRegionGrowth, and the surface points at its centre, eyes
  // and chin line (the box's vertical midline).
  struct Seen {
    std::vector<bool> faces;
    std::optional<Vec3> centre, eyes, chin;
  };
  Seen seen(const Detection& d) const {
    const Image ids = render_view(d.turn, [](int f, const Vec3&) {
      return std::array<double, 3>{double(f & 255), double((f >> 8) & 255), double((f >> 16) & 255)};
    });
    auto face_at = [&](double x, double y) -> int {
      const int px = std::clamp(static_cast<int>(x), 0, ids.width - 1), py = std::clamp(static_cast<int>(y), 0, ids.height - 1);
      const uint8_t* p = ids.at(px, py);
      const int f = p[0] | (p[1] << 8) | (p[2] << 16);
      return f == kNoFace ? -1 : f;
    };
    Seen s;
    s.faces.assign(mesh_.faces.size(), false);
    const double cx = d.box.x + 0.5 * d.box.width, cy = d.box.y + 0.5 * d.box.height, half = 0.5 * kRegionGrowth * d.box.width;
    for (int y = static_cast<int>(cy - half); y <= static_cast<int>(cy + half); ++y) {
      for (int x = static_cast<int>(cx - half); x <= static_cast<int>(cx + half); ++x) {
        if (x < 0 || y < 0 || x >= ids.width || y >= ids.height) continue;
        if (const int f = face_at(x, y); f >= 0) s.faces[static_cast<size_t>(f)] = true;
      }
    }
    auto point_at = [&](double y_share) -> std::optional<Vec3> {
      const int f = face_at(cx, d.box.y + y_share * d.box.height);
      if (f < 0) return std::nullopt;
      const Face& t = mesh_.faces[static_cast<size_t>(f)];
      return (mesh_.positions[static_cast<size_t>(t[0])] + mesh_.positions[static_cast<size_t>(t[1])] +
              mesh_.positions[static_cast<size_t>(t[2])]) /
             3;
    };
    s.centre = point_at(kBoxCentreY);
    s.eyes = point_at(kBoxEyesY);
    s.chin = point_at(kBoxChinY);
    return s;
  }

 private:
  static constexpr int kNoFace = 0xFFFFFF;  // the id buffer's background (white)

  // The mesh turned by `turn`, drawn unlit by `shader`; triangles facing away from the camera are
  // drawn as background (the back of an open face is a mirrored face to a detector).
  Image render_view(const Eigen::Matrix3d& turn, const SurfaceShader& shader) const {
    TriangleMesh turned;
    turned.faces = mesh_.faces;
    turned.positions.reserve(mesh_.positions.size());
    for (const Vec3& p : mesh_.positions) turned.positions.push_back(turn * p);
    RenderOptions options;
    options.width = options.height = kViewSize;
    options.margin = 0.02;
    options.shading = false;
    options.background = {255, 255, 255};
    auto front_only = [&turned, &shader](int f, const Vec3& bary) {
      const Face& t = turned.faces[static_cast<size_t>(f)];
      const Vec3 &a = turned.positions[static_cast<size_t>(t[0])], &b = turned.positions[static_cast<size_t>(t[1])],
                 &c = turned.positions[static_cast<size_t>(t[2])];
      if ((b - a).cross(c - a).z() <= 0) return std::array<double, 3>{255, 255, 255};
      return shader(f, bary);
    };
    return render(turned, front_only, options);
  }

  const TriangleMesh& mesh_;
  SurfaceShader colour_;
};

// The face in the texture, its region read by the geometry where it can be; nullopt (and `why`)
// where no face is detected.
std::optional<FaceOrientation> find_by_texture(const TriangleMesh& mesh, const Image* texture, const std::string& name, std::string* why) {
  Image named;  // the mesh's own texture file, read only when no image was given and this step is reached
  if ((!texture || texture->empty()) && mesh.has_uvs() && !mesh.texture.empty()) {
    try {
      named = read_image(mesh.texture);
      texture = &named;
    } catch (const Error& e) {
      *why = std::string("its texture could not be read: ") + e.what();
      return std::nullopt;
    }
  }
  const TextureFaceFinder finder(mesh, texture);
  if (*why = finder.unavailable(); !why->empty()) return std::nullopt;
  const std::optional<Detection> d = finder.detect();
  if (!d) {
    *why = "no face detected in views of the textured surface";
    return std::nullopt;
  }
  const TextureFaceFinder::Seen seen = finder.seen(*d);
  if (!seen.centre || !seen.eyes || !seen.chin) {
    *why = "the face detected in the texture is not on the surface";
    return std::nullopt;
  }
  // A detection alone is at most half-sure: the box places the face, but its up and tip are coarse
  // (3-20° and up to 3.5% of the diagonal off on the test's scans).
  const double texture_confidence = 0.5 * std::min(1.0, static_cast<double>(d->neighbours) / kConfidentNeighbours);
  const Vec3 towards = d->turn.transpose() * Vec3::UnitZ();  // out of the face, towards the camera
  Vec3 vertical = *seen.eyes - *seen.chin;
  vertical = (vertical - vertical.dot(towards) * towards).normalized();
  // The region read as the face: the surface within 1.5 eyes-to-chin of the box's centre (the
  // detector's box, grown, takes hair beside the face that spoils the mirror plane).
  const double reach = 1.5 * (*seen.eyes - *seen.chin).norm();
  std::vector<bool> near(mesh.faces.size(), false);
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    near[f] = true;
    for (int k = 0; k < 3; ++k) near[f] = near[f] && (mesh.positions[static_cast<size_t>(mesh.faces[f][k])] - *seen.centre).norm() < reach;
  }
  const TriangleMesh region = sub_mesh(mesh, near);
  try {
    FaceOrientation o = find_face_orientation(region, name, &vertical, region_up_scale(mesh));
    if (o.vertical.dot(vertical) >= kMinAgreementCosine) {
      o.method = FaceFindingMethod::kTexture;
      o.confidence = 1 - (1 - texture_confidence) * (1 - geometry_confidence(o));
      return o;
    }
  } catch (const Error&) {
    // The region is no face to the geometry; the texture alone says where it is.
  }
  FaceOrientation o;
  o.method = FaceFindingMethod::kTexture;
  o.confidence = texture_confidence;
  o.facing = towards;
  o.vertical = vertical;
  o.facing_share = area_weighted_normal(region).norm();
  // The nose tip: the region's most protruding point towards the camera near the box's centre.
  const PointToMesh surface(region);
  const SurfacePoint c = surface.closest(*seen.centre);
  const Face& f = region.faces[static_cast<size_t>(c.face)];
  o.nose_tip = c.bary[0] * region.positions[static_cast<size_t>(f[0])] + c.bary[1] * region.positions[static_cast<size_t>(f[1])] +
               c.bary[2] * region.positions[static_cast<size_t>(f[2])];
  o.up = *seen.eyes;
  o.up_evidence = 0;
  return o;
}

// ---- The face region: the mirror plane of balls about the most protruding point ----

bool has_rim(const TriangleMesh& mesh) {
  const MeshTopology topology(mesh.faces, static_cast<int>(mesh.positions.size()));
  for (int e = 0; e < topology.edge_count(); ++e) {
    if (topology.is_boundary_edge(e)) return true;
  }
  return false;
}

// From the centroid of the rim's vertices (a whole head's neck) to that of all vertices: up, for a
// head whose rim is its neck. Zero without a rim.
Vec3 away_from_rim(const TriangleMesh& mesh) {
  const MeshTopology topology(mesh.faces, static_cast<int>(mesh.positions.size()));
  Vec3 rim = Vec3::Zero(), all = Vec3::Zero();
  int on_rim = 0;
  for (int v = 0; v < mesh.vertex_count(); ++v) {
    all += mesh.positions[static_cast<size_t>(v)];
    if (topology.is_boundary_vertex(v)) rim += mesh.positions[static_cast<size_t>(v)], ++on_rim;
  }
  if (on_rim == 0) return Vec3::Zero();
  return all / mesh.vertex_count() - rim / on_rim;
}

// The directions a whole head's face region is looked for along: the 26 of a cube's faces, edges
// and corners (at most 35 degrees from any direction).
std::vector<Vec3> search_directions() {
  std::vector<Vec3> out;
  for (int x = -1; x <= 1; ++x) {
    for (int y = -1; y <= 1; ++y) {
      for (int z = -1; z <= 1; ++z) {
        if (x != 0 || y != 0 || z != 0) out.push_back(Vec3(x, y, z).normalized());
      }
    }
  }
  return out;
}

std::optional<FaceOrientation> find_by_region(const TriangleMesh& mesh, const std::string& name, const Vec3* vertical_hint,
                                              const Vec3* facing_hint, const FaceFindingOptions& options, std::string* why) {
  const std::function<void(int, int)>& progress = options.progress;
  const Vec3 mean = area_weighted_normal(mesh);                    // a sum of cross products: twice the area-weighted normal
  const double area = 2 * total_area(mesh.positions, mesh.faces);  // on the same scale
  // A whole head faces no one way (its mean normal is the neck's opening's, pointing up): its face
  // is looked for about the most protruding point along each of 26 directions, the surest region
  // winning (a face's nose, sockets and symmetry against a dome's or the back of the head's).
  // Where the scan's holes say where the face is (the filled eyes', mouth's and nostrils' centroids,
  // from find_face_facing), that direction alone. Either way up is the side away from the neck rim.
  std::vector<Vec3> starts;
  Vec3 up_side = Vec3::Zero();  // a whole head's: away from its neck rim
  if (mean.norm() >= kWholeHeadFacingShare * area) {
    starts.push_back(mean.normalized());
  } else if (!has_rim(mesh)) {
    // A head scan has a rim (the neck's, at least); a closed surface (a ball) is no head, and a
    // region of it is symmetric every way, so it would pass for a face.
    *why = "no region faces one way, and a closed surface has no neck rim to be a whole head";
    return std::nullopt;
  } else if (facing_hint != nullptr) {
    starts.push_back(facing_hint->normalized());
    up_side = away_from_rim(mesh);
  } else {
    starts = search_directions();
    up_side = away_from_rim(mesh);
  }
  if (!(area > 0)) {
    *why = "no region faces one way";
    return std::nullopt;
  }
  const double diagonal = bounding_box_diagonal(mesh.positions);
  std::optional<FaceOrientation> best;
  std::string last = "no region was tried";
  // Around a whole head, the back and the crown are domes as symmetric as a face: what tells the
  // face is its nose (geometry_shows_face) and that it says which way is up by itself (the nose's
  // profile, the eye sockets), where a dome takes up from the hint or barely reads it. Among regions
  // sure of their mirror plane (kWholeHeadSure) with a nose, the one whose up evidence is the
  // strongest; otherwise the surest. (Without the nose, the back of fmsynth's head won: 0.019.)
  const auto better = [whole_head = starts.size() > 1](const FaceOrientation& a, const FaceOrientation& b) {
    if (whole_head) {
      const auto evidence = [](const FaceOrientation& o) {
        return o.confidence >= kWholeHeadSure && !o.up_from_hint && geometry_shows_face(o) ? o.up_evidence : -1.0;
      };
      if (evidence(a) != evidence(b)) return evidence(a) > evidence(b);
    }
    return a.confidence > b.confidence;
  };
  // The region about the most protruding vertex along `start` within `reach` of the diagonal, and
  // that vertex; nullopt where that region (reach, tip) was read already. Nearby directions often
  // end at the same tip, and the region is the tip's: read again it could not win over itself.
  std::vector<std::pair<double, size_t>> read;  // (reach, tip) of the regions read
  const auto region_about = [&](const Vec3& start, double reach) -> std::optional<std::vector<bool>> {
    // About the most protruding vertex along the facing of the region itself (the shoulders turn the
    // whole scan's mean normal), found twice: from the whole scan's, then from the first region's.
    Vec3 facing = start;
    std::vector<bool> keep(mesh.faces.size(), false);
    for (int round = 0; round < 2; ++round) {
      size_t tip = 0;
      for (size_t v = 1; v < mesh.positions.size(); ++v) {
        if (mesh.positions[v].dot(facing) > mesh.positions[tip].dot(facing)) tip = v;
      }
      if (round == 1) {
        if (std::find(read.begin(), read.end(), std::make_pair(reach, tip)) != read.end()) return std::nullopt;
        read.emplace_back(reach, tip);
      }
      for (size_t f = 0; f < mesh.faces.size(); ++f) {
        keep[f] = true;
        for (int k = 0; k < 3; ++k)
          keep[f] = keep[f] && (mesh.positions[static_cast<size_t>(mesh.faces[f][k])] - mesh.positions[tip]).norm() < reach * diagonal;
      }
      const Vec3 n = area_weighted_normal(sub_mesh(mesh, keep));
      if (!(n.norm() > 0)) break;
      facing = n.normalized();
    }
    return keep;
  };
  const auto read_region = [&](const std::vector<bool>& keep, const MirrorSearch& search) -> std::optional<FaceOrientation> {
    try {
      FaceOrientation o = find_face_orientation_up_side(sub_mesh(mesh, keep), name, vertical_hint, region_up_scale(mesh),
                                                        up_side.norm() > 0 ? &up_side : nullptr, search);
      o.method = FaceFindingMethod::kFaceRegion;
      o.confidence = geometry_confidence(o);
      return o;
    } catch (const Error& e) {
      last = reason_of(e, name);
      return std::nullopt;
    }
  };
  // Around a whole head without holes, a first pass ranks the directions by a coarse reading of
  // their largest regions (kCoarseMirrorSearch), and only the kRefinedDirections best are read in
  // full at every reach: reading all 78 regions in full took about 17 s a frame of fmsynth --head.
  int first = 0;  // the progress steps of the first pass
  if (options.coarse_first_pass && starts.size() > kRefinedDirections) {
    first = static_cast<int>(starts.size());
    std::vector<std::pair<FaceOrientation, Vec3>> ranked;
    for (size_t i = 0; i < starts.size(); ++i) {
      if (progress) progress(static_cast<int>(i), first + static_cast<int>(kRefinedDirections * kRegionReaches.size()));
      if (const std::optional<std::vector<bool>> keep = region_about(starts[i], kRegionReaches.front())) {
        if (const std::optional<FaceOrientation> o = read_region(*keep, kCoarseMirrorSearch)) ranked.emplace_back(*o, starts[i]);
      }
    }
    std::stable_sort(ranked.begin(), ranked.end(), [&](const auto& a, const auto& b) { return better(a.first, b.first); });
    starts.clear();
    for (size_t i = 0; i < ranked.size() && i < kRefinedDirections; ++i) starts.push_back(ranked[i].second);
    read.clear();
  }
  const int total = first + static_cast<int>(kRegionReaches.size() * starts.size());
  int done = first;
  for (double reach : kRegionReaches) {
    for (const Vec3& start : starts) {
      if (progress) progress(done++, total);
      const std::optional<std::vector<bool>> keep = region_about(start, reach);
      if (!keep) continue;
      if (std::optional<FaceOrientation> o = read_region(*keep, MirrorSearch{})) {
        if (!best || better(*o, *best)) best = o;
      }
    }
  }
  if (progress) progress(total, total);
  if (!best)
    *why = last + " (in regions of " + std::to_string(static_cast<int>(100 * kRegionReaches.back())) + "-" +
           std::to_string(static_cast<int>(100 * kRegionReaches.front())) + "% of the diagonal about the most protruding point)";
  return best;
}

}  // namespace

namespace {

constexpr EnumName<FaceFindingMethod> kFaceFindingMethodNames[] = {{FaceFindingMethod::kWholeSurface, "whole surface"},
                                                                   {FaceFindingMethod::kTexture, "texture"},
                                                                   {FaceFindingMethod::kFaceRegion, "face region"}};

}  // namespace

const char* face_finding_method_name(FaceFindingMethod method) { return name_of(kFaceFindingMethodNames, method); }

FaceOrientation find_face(const TriangleMesh& mesh, const Image* texture, const std::string& name, const Vec3* vertical_hint,
                          const FaceFindingOptions& options) {
  return find_face_facing(mesh, texture, name, vertical_hint, nullptr, options);
}

FaceOrientation find_face_facing(const TriangleMesh& mesh, const Image* texture, const std::string& name, const Vec3* vertical_hint,
                                 const Vec3* facing_hint, const FaceFindingOptions& options) {
  std::vector<std::string> reasons;
  std::vector<FaceOrientation> found;  // each step's finding, where it found one
  if (options.whole_surface) {
    try {
      FaceOrientation o = find_face_orientation(mesh, name, vertical_hint);
      o.method = FaceFindingMethod::kWholeSurface;
      o.confidence = geometry_confidence(o);
      if (o.confidence >= kSureConfidence && geometry_shows_face(o)) return o;
      found.push_back(o);
    } catch (const Error& e) {
      if (e.code() != ErrorCode::kInvalidArgument) throw;
      reasons.push_back(reason_of(e, name));
    }
  }
  if (mesh.faces.empty()) refuse_face_orientation(name, "the surface has no faces");
  std::string why;
  std::optional<FaceOrientation> by_texture;
  if (options.texture) {
    by_texture = find_by_texture(mesh, texture, name, &why);
    if (by_texture) {
      found.push_back(*by_texture);
    } else {
      reasons.push_back("texture: " + why);
    }
  }
  if (options.face_region) {
    if (std::optional<FaceOrientation> o = find_by_region(mesh, name, vertical_hint, facing_hint, options, &why)) {
      // The texture's face, where it agrees, confirms the region's: two independent readings.
      if (by_texture && o->vertical.dot(by_texture->vertical) >= kMinAgreementCosine &&
          o->facing.dot(by_texture->facing) >= kMinAgreementCosine) {
        o->confidence = 1 - (1 - o->confidence) * (1 - by_texture->confidence);
      }
      found.push_back(*o);
    } else {
      reasons.push_back("face region: " + why);
    }
  }
  // Where the texture shows a face, every finding stands; where it does not, a geometric finding
  // must show a face's shape, not only a mirror plane (a dome beside hair has one as good).
  std::optional<FaceOrientation> best;
  std::vector<std::string> not_faces;
  double face_confidence = 0;  // of the findings refused: the surest's, their mirror plane's times their nose's
  for (const FaceOrientation& o : found) {
    if (!by_texture && !geometry_shows_face(o)) {
      not_faces.push_back(no_face_shape(o));
      face_confidence = std::max(face_confidence, o.confidence * face_shape_confidence(o));
      continue;
    }
    if (!best || o.confidence > best->confidence) best = o;
  }
  if (best) return *best;
  if (reasons.empty() && not_faces.empty()) refuse_face_orientation(name, "every way of finding a face was turned off");
  // Each step's reason, and each geometric finding's measure of why it is no face.
  std::string all;
  for (const std::string& r : not_faces) all += (all.empty() ? "" : "; ") + r;
  for (const std::string& r : reasons) all += (all.empty() ? "" : "; ") + r;
  char confidence[64];
  std::snprintf(confidence, sizeof confidence, "; face confidence %.2f", face_confidence);
  throw Error(ErrorCode::kInvalidArgument, name + ": no face found: neither the geometry nor the texture shows a face (" + all +
                                               confidence + ") (give the capture its landmarks nose_tip and nose_bridge)");
}

}  // namespace facemorph
