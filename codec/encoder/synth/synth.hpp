// Synthetic face captures: facemorph's own test and demo data (spec/capture.md §"fmsynth").
//
// The face is an analytic open surface with disk topology: a point m = (s, t) of the material
// ellipse (s/a)² + (t/b)² <= 1 (metres) is carried to
//     P(m, τ) = (m + D(m, e(τ)), h(m, e(τ)))        (x right, y up, z towards the viewer)
// where e(τ) are the expression weights at time τ (blink, jaw, smile, brow, pucker), D a small
// in-plane displacement (a diffeomorphism of the plane) and h a height: an ellipsoidal cap with
// brow, eye sockets, nose, lips, cheeks and chin built from Gaussian bumps. Texture and landmarks
// are attached to material points, so they move with the skin. The exact surface is available at
// any τ (SyntheticFace::position), which is the ground truth tests and benchmarks compare against.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/core/image/image.hpp"

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace facemorph {

enum class Expression { kBlink, kMouth, kSmile, kTalk, kMixed };

// "blink" etc.; throws kInvalidArgument for an unknown name.
Expression parse_expression(const std::string& name);
const char* expression_name(Expression expression);

// Expression weights, each in [0, 1].
struct ExpressionWeights {
  double blink = 0;   // eyelids closed
  double jaw = 0;     // mouth open
  double smile = 0;   // corners out and up, cheeks raised
  double brow = 0;    // brows raised
  double pucker = 0;  // corners drawn in
};

// Scanner defects fmsynth --defects writes into every frame, each a kind the encoder's preparation
// repairs (spec/method.md §2.1). Placed at fixed material points, so every frame has the same ones.
enum DefectKind : uint32_t {
  kDefectBowTies = 1,          // two wedges cut out at a vertex (a pinched hole) and a flap touching at one vertex
  kDefectThreeFaceEdges = 2,   // fins: a face standing on an interior edge
  kDefectDuplicateFaces = 4,   // faces repeated (as written, rotated, reversed)
  kDefectDegenerateFaces = 8,  // faces with a repeated vertex, and a zero-area sliver of three distinct vertices in a line
  kDefectFlippedPatch = 16,    // a patch of faces wound the other way
  kDefectIslands = 32,         // specks floating beside the face
  kDefectTorso = 64,           // a hair/torso surface fused to the face along a seam of edges
  kDefectAll = 127,
};

// "all", or names separated by commas: bow-ties, three-face-edges, duplicates, degenerate, flipped,
// islands, torso. Throws kInvalidArgument naming an unknown one.
uint32_t parse_defects(const std::string& list);
std::string defect_names(uint32_t defects);  // the comma-separated names, in the order above

// What add_defects wrote: the counts a repair of the frame must find.
struct DefectCounts {
  int bow_ties = 0;          // bow-tie vertices (pinched holes and flaps)
  int flaps = 0;             // of which flaps: one face touching the face at a vertex (a speck once split)
  int three_face_edges = 0;  // fins' edges plus the torso's seam edges
  int fins = 0;
  int duplicate_faces = 0;
  int degenerate_faces = 0;
  int slivers = 0;  // of which slivers: each closes a T-junction, so the repair splits the face across it
  int flipped_faces = 0;
  int islands = 0;
  int island_faces = 0;
  int torso_faces = 0;
  int seam_edges = 0;
};

// Writes the `defects` into `mesh`, a frame of a SyntheticFace whose vertex i sits at material point
// `material[i]` (the first `boundary_count` on the rim). Texture coordinates and colours, where the
// mesh has them, stay one per vertex (uv_faces equal to faces). Returns what it wrote.
DefectCounts add_defects(TriangleMesh& mesh, const std::vector<Vec2>& material, int boundary_count, uint32_t defects);

struct SynthOptions {
  int frames = 60;
  double fps = 30;
  Expression expression = Expression::kMixed;
  int vertices = 20000;            // target per frame (±10 % per frame with remesh)
  bool remesh = false;             // every frame its own sampling and connectivity
  double noise = 0.0005;           // metres, Gaussian, along the normal
  uint64_t seed = 1;               // face identity, texture detail, noise, remeshing
  int texture_size = 1024;         // pixels per side of each frame's texture
  double head_motion_degrees = 0;  // amplitude of a slow rigid head rotation (0: none)
  // The mouth's speed in `talk` and `mixed`: its jaw and lip motion at speech_rate times the normal
  // pace (fast speech for the rate bench, issue 44); 1 leaves every capture as it was.
  double speech_rate = 1;
  // Colour per vertex instead of a texture: each frame a binary PLY with red/green/blue (uchar, the
  // skin's colour at the vertex) and neither UVs nor image, as depth cameras write (spec/capture.md).
  bool vertex_colour = false;
  // One texture image (texture.jpg, the skin at time 0) that every frame's material names, as a
  // capture whose rig paints one atlas for the whole take: only the geometry moves.
  bool shared_texture = false;
  uint32_t defects = 0;  // DefectKind flags written into every frame (fmsynth --defects)
  // Eyes, mouth and nostrils left open, as a scanner leaves them (fmsynth --holes): the faces whose
  // material centroid lies in one of five fixed ellipses are not written.
  bool holes = false;
  // The whole head (fmsynth --head): the face closed round the back of the head down to a neck,
  // whose rim is the surface's outer boundary (rim_* markers lie on it). Not with --remesh,
  // --defects or --vertex-colour.
  bool whole_head = false;
  // A head-and-shoulders scan (fmsynth --surround): hair and a shoulder round the face, textured
  // (surrounded_frame). Not with --remesh, --defects, --holes, --head or --vertex-colour.
  bool surround = false;
  // With surround: a plain dome and bare skin where the face was (fmsynth --no-face): no face, and
  // no landmarks written.
  bool no_face = false;
};

struct HeadVertex;

struct NamedPoint {
  std::string name;
  Vec2 material;  // where it sits on the material ellipse
};

class SyntheticFace {
 public:
  SyntheticFace(Expression expression, uint64_t seed, double head_motion_degrees = 0, double speech_rate = 1);

  static constexpr double kHalfWidth = 0.08;   // a: material ellipse semi-axis along x (m)
  static constexpr double kHalfHeight = 0.10;  // b: along y (m)

  ExpressionWeights weights(double time) const;
  // The exact surface point of material point m at time τ (metres).
  Vec3 position(const Vec2& material, double time) const;
  // Unit normal of the exact surface (pointing towards the viewer, +z at rest).
  Vec3 normal(const Vec2& material, double time) const;
  // Texture colour (sRGB, 0..255) of material point m at time τ.
  std::array<uint8_t, 3> color(const Vec2& material, double time) const;

  // Named landmarks (>= 20, including rim_0..rim_7 on the boundary), as material points.
  const std::vector<NamedPoint>& landmarks() const { return landmarks_; }
  // Boundary of the material ellipse at angle θ (radians, 0 = +x, counter-clockwise).
  static Vec2 rim_point(double theta);
  // Texture coordinate of a material point: the ellipse's bounding box mapped to [0,1]².
  static Vec2 texture_coordinate(const Vec2& material);

  // Exact, noise-free surface at τ on a fixed dense lattice of about `vertices` vertices.
  TriangleMesh truth_mesh(double time, int vertices) const;

  // The face before the head's rigid motion (the whole head's back follows its rim from it).
  Vec3 unposed_position(const Vec2& material, double time) const;
  // A vertex of the back of the head (sample_head) at time τ.
  Vec3 head_point(const HeadVertex& vertex, double time) const;
  // Whether a material point lies in one of the holes fmsynth --holes leaves (eyes, mouth, nostrils).
  static bool in_hole(const Vec2& material);
  // The neck rim of the whole head: unit directions from the head's centre, θ in radians.
  static Vec3 neck_rim_direction(double theta);

  Expression expression() const { return expression_; }
  uint64_t seed() const { return seed_; }
  double head_motion_degrees() const { return head_motion_degrees_; }
  double speech_rate() const { return speech_rate_; }

 private:
  double height(const Vec2& m, const ExpressionWeights& w) const;
  Vec2 displacement(const Vec2& m, const ExpressionWeights& w) const;
  Vec3 head_pose(const Vec3& p, double time) const;

  Expression expression_;
  uint64_t seed_;
  double head_motion_degrees_;
  double speech_rate_;
  double identity_[6];  // per-seed feature scale factors
  std::vector<NamedPoint> landmarks_;
  std::vector<std::array<double, 4>> freckles_;  // (s, t, radius, darkness)
};

// Material sample points of one frame: boundary samples (first, in counter-clockwise order) then
// interior points, and their Delaunay triangulation. `frame_seed` varies the sampling when remeshing.
struct MaterialSampling {
  std::vector<Vec2> points;
  std::vector<Face> faces;
  int boundary_count = 0;
};
MaterialSampling sample_material_ellipse(int vertices, bool jitter_per_frame, uint64_t frame_seed);

// A vertex of the back of the synthetic head: where it is at rest (unposed, time 0) and the two
// face rim points (material angles) whose motion it follows, by weight join_weight (1 on the rim,
// 0 from 25 degrees beyond it).
struct HeadVertex {
  Vec3 rest = Vec3::Zero();
  std::array<double, 2> rim_theta = {0, 0};
  double rim_mix = 0;  // 0: the first rim point, 1: the second
  double join_weight = 0;
  Vec3 normal = Vec3::UnitZ();  // outward, about (the ray from the head's centre): scanner noise goes along it
  Vec2 plane = Vec2::Zero();    // its stereographic image (the back's texture coordinates are made from it)
};

// A frame's connectivity for --holes and --head: the face's fixed lattice (its first face_vertices
// vertices, face.points in order) and, for the whole head, the back's vertices after them (the neck
// rim's neck_count first). `faces` index that vertex list.
struct HeadSampling {
  MaterialSampling face;
  int face_vertices = 0;
  std::vector<HeadVertex> back;
  int neck_count = 0;
  std::vector<Vec2> rim_plane;  // the stereographic images of the face's rim vertices
  std::vector<Face> faces;      // the face's (face_faces of them), then the back's
  size_t face_faces = 0;
};
HeadSampling sample_head(int face_vertices, const SyntheticFace& face, bool holes, bool whole_head);

// fmsynth --surround: the face inside a head-and-shoulders scan, 0.44 x 0.54 m of the face's
// material plane (the face's ellipse in the middle): hair heaped on the left (seen from the front),
// a shoulder forward on the right, textured with the face, hair, skin and a shirt. With `with_face`
// false (fmsynth --no-face), the same surround with a plain dome and bare skin where the face was:
// no face to find, which --landmarks auto refuses by name (spec/method.md §7.14).
struct SurroundedFrame {
  TriangleMesh mesh;  // UVs per vertex over the whole extent (uv_faces equal to faces)
  Image texture;      // 800 pixels a metre
};
// The scan's material points: a grid `spacing` apart over the extent, jittered inside by up to 0.3
// of the spacing (by `seed`); the edge's points unjittered, so the rim is the extent's rectangle.
std::vector<Vec2> surround_material(double spacing, uint64_t seed);
double surround_spacing(int vertices);  // the spacing that gives about `vertices` vertices
// Frame `time` of `face` on those points and their triangles, turned by `pose`.
SurroundedFrame surrounded_frame(const SyntheticFace& face, const std::vector<Vec2>& material, const std::vector<Face>& faces, double time,
                                 const Eigen::Matrix3d& pose, bool with_face);
// The same, triangulating surround_material(spacing, seed) itself.
SurroundedFrame surrounded_frame(const SyntheticFace& face, double spacing, uint64_t seed, double time, const Eigen::Matrix3d& pose,
                                 bool with_face);

// Progress callback: (frames done, frames total).
using ProgressCallback = std::function<void(int, int)>;

// Writes a capture (capture.json, frame_NNNN.obj/.mtl/.jpg or with vertex_colour frame_NNNN.ply, landmarks.csv) into `directory`,
// creating it. Throws facemorph::Error on failure (kIo naming the file, kInvalidArgument).
void write_synthetic_capture(const std::filesystem::path& directory, const SynthOptions& options, const ProgressCallback& progress = {});

}  // namespace facemorph
