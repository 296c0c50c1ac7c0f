// Incremental Bowyer-Watson triangulation, internal and header-only: the one insertion loop behind
// both Delaunay triangulations, the exact one that defines G (exact_delaunay.cpp, decoder) and the
// float one the encoder and the tools use (meshkit's delaunay.cpp). What differs between them comes
// in as Predicates:
//   static constexpr const char* kName;                 // names the triangulation in its errors
//   orientation(const Point& a, const Point& b, const Point& c)  // > 0 counter-clockwise, < 0 clockwise
//   bool in_circle(const Point& a, const Point& b, const Point& c, const Point& q)
//                                                       // q strictly inside the circle of (a, b, c)
// and each caller orders the points (along hilbert_index) and decides what a repeated point means.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "format/error.hpp"

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace facemorph::bowyer_watson {

// Position along a Hilbert curve of order 16; inserting in this order keeps point-location walks short.
inline uint64_t hilbert_index(uint32_t x, uint32_t y) {
  uint64_t d = 0;
  for (uint32_t s = 1u << 15; s > 0; s >>= 1) {
    const uint32_t rx = (x & s) > 0, ry = (y & s) > 0;
    d += uint64_t{s} * s * ((3 * rx) ^ ry);
    if (ry == 0) {
      if (rx == 1) {
        x = s - 1 - (x & (s - 1)) + (x & ~(s - 1));
        y = s - 1 - (y & (s - 1)) + (y & ~(s - 1));
      }
      std::swap(x, y);
    }
  }
  return d;
}

struct Triangle {
  std::array<int32_t, 3> v;
  std::array<int32_t, 3> n;  // n[k]: neighbour across the edge opposite v[k]; -1 none
};

template <typename Point, typename Predicates>
class Triangulation {
 public:
  // `points` holds the input points and, last, the three vertices of a counter-clockwise super
  // triangle that contains them all with their circumcircles; both must outlive the triangulation.
  Triangulation(std::span<const Point> points, Predicates& predicates)
      : points_(points), predicates_(predicates), super_(static_cast<int32_t>(points.size()) - 3) {
    triangles_.push_back({{super_, super_ + 1, super_ + 2}, {-1, -1, -1}});
    alive_.push_back(1);
    stamp_.push_back(0);
  }

  // Inserts point `index`. False, and nothing changes, when it repeats a vertex of the triangle
  // that contains it. Throws kNumerical when the predicates leave the cavity not star-shaped.
  bool insert(int32_t index) {
    const Point& q = p(index);
    const int32_t start = locate(q);
    for (int32_t v : triangles_[static_cast<size_t>(start)].v) {
      if (p(v) == q) return false;
    }
    ++epoch_;
    cavity_.assign(1, start);
    stamp_[static_cast<size_t>(start)] = epoch_;
    for (size_t i = 0; i < cavity_.size(); ++i) {
      const Triangle& t = triangles_[static_cast<size_t>(cavity_[i])];
      for (int32_t nb : t.n) {
        if (nb < 0 || stamp_[static_cast<size_t>(nb)] == epoch_) continue;
        const Triangle& u = triangles_[static_cast<size_t>(nb)];
        if (predicates_.in_circle(p(u.v[0]), p(u.v[1]), p(u.v[2]), q)) {
          stamp_[static_cast<size_t>(nb)] = epoch_;
          cavity_.push_back(nb);
        }
      }
    }
    // The cavity's boundary edges, each becoming a new triangle (a, b, q).
    rims_.clear();
    for (int32_t c : cavity_) {
      const Triangle& t = triangles_[static_cast<size_t>(c)];
      for (int k = 0; k < 3; ++k) {
        const int32_t nb = t.n[static_cast<size_t>(k)];
        if (nb >= 0 && stamp_[static_cast<size_t>(nb)] == epoch_) continue;
        const int32_t a = t.v[static_cast<size_t>((k + 1) % 3)], b = t.v[static_cast<size_t>((k + 2) % 3)];
        if (predicates_.orientation(p(a), p(b), q) <= 0) {
          throw Error(ErrorCode::kNumerical,
                      std::string(Predicates::kName) + ": the cavity is not star-shaped at point " + std::to_string(index));
        }
        int32_t slot = -1;
        if (nb >= 0) {
          for (int m = 0; m < 3; ++m) {
            if (triangles_[static_cast<size_t>(nb)].n[static_cast<size_t>(m)] == c) slot = m;
          }
        }
        rims_.push_back({a, b, nb, slot});
      }
    }
    for (int32_t c : cavity_) {
      alive_[static_cast<size_t>(c)] = 0;
      free_.push_back(c);
    }
    created_.clear();
    for (const Rim& rim : rims_) {
      int32_t id;
      if (!free_.empty()) {
        id = free_.back();
        free_.pop_back();
      } else {
        id = static_cast<int32_t>(triangles_.size());
        triangles_.push_back({});
        alive_.push_back(0);
        stamp_.push_back(0);
      }
      triangles_[static_cast<size_t>(id)] = {{rim.a, rim.b, index}, {-1, -1, rim.outside}};
      alive_[static_cast<size_t>(id)] = 1;
      if (rim.outside >= 0) triangles_[static_cast<size_t>(rim.outside)].n[static_cast<size_t>(rim.outside_slot)] = id;
      created_.push_back(id);
    }
    // Link the fan: triangle (a, b, q) meets (b, c, q) across edge (b, q), opposite its vertex a.
    for (int32_t id : created_) {
      Triangle& t = triangles_[static_cast<size_t>(id)];
      for (int32_t other : created_) {
        const Triangle& u = triangles_[static_cast<size_t>(other)];
        if (u.v[0] == t.v[1]) t.n[0] = other;  // u starts where t ends
        if (u.v[1] == t.v[0]) t.n[1] = other;  // u ends where t starts
      }
    }
    last_ = created_.front();
    return true;
  }

  // The triangles without a super vertex, counter-clockwise, in the order of their slots.
  std::vector<Face> faces() const {
    std::vector<Face> faces;
    for (size_t t = 0; t < triangles_.size(); ++t) {
      const auto& v = triangles_[t].v;
      if (alive_[t] && v[0] < super_ && v[1] < super_ && v[2] < super_) faces.push_back({v[0], v[1], v[2]});
    }
    return faces;
  }

 private:
  const Point& p(int32_t i) const { return points_[static_cast<size_t>(i)]; }

  // The triangle containing q, by walking from the last one created.
  int32_t locate(const Point& q) const {
    int32_t t = last_;
    for (size_t steps = 0; steps < 4 * triangles_.size() + 16; ++steps) {
      const Triangle& tri = triangles_[static_cast<size_t>(t)];
      int32_t next = -1;
      for (int k = 0; k < 3; ++k) {
        const int k1 = (k + 1 + static_cast<int>(steps % 3)) % 3;  // rotate the test order: no cycling
        if (predicates_.orientation(p(tri.v[static_cast<size_t>((k1 + 1) % 3)]), p(tri.v[static_cast<size_t>((k1 + 2) % 3)]), q) < 0) {
          next = tri.n[static_cast<size_t>(k1)];
          break;
        }
      }
      if (next < 0) return t;
      t = next;
    }
    throw Error(ErrorCode::kNumerical, std::string(Predicates::kName) + ": point location did not terminate");
  }

  // A cavity boundary edge (a, b) and the triangle outside it (and the slot pointing back).
  struct Rim {
    int32_t a, b, outside, outside_slot;
  };

  std::span<const Point> points_;
  Predicates& predicates_;
  int32_t super_;
  std::vector<Triangle> triangles_;
  std::vector<uint8_t> alive_;
  std::vector<uint32_t> stamp_;  // stamp_[t] == epoch_: t is in the current cavity
  uint32_t epoch_ = 0;
  std::vector<int32_t> cavity_, free_, created_;
  std::vector<Rim> rims_;
  int32_t last_ = 0;
};

}  // namespace facemorph::bowyer_watson
