#include "codec/core/reconstruct/lattice_multigrid.hpp"

#include "format/error.hpp"

#include <Eigen/SparseCholesky>

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace facemorph {

namespace {

// Below this many unknowns a level is solved directly: a coarser lattice would hardly be a disk.
constexpr Eigen::Index kCoarsestSize = 600;

using RowMajorSparse = Eigen::SparseMatrix<double, Eigen::RowMajor>;

// The x, y, z of a point (and a lane of padding): one SIMD operation per matrix entry.
typedef float Float4 __attribute__((vector_size(16)));

// Bilinear prolongation from the even points of `cells` to all of them; `coarse_cells` receives the
// coarse lattice's points ((i/2, j/2), in the fine order).
SparseMatrix bilinear_prolongation(const std::vector<std::array<int32_t, 2>>& cells, std::vector<std::array<int32_t, 2>>& coarse_cells) {
  auto key = [](int32_t i, int32_t j) { return (static_cast<int64_t>(i) << 32) ^ static_cast<uint32_t>(j); };
  std::unordered_map<int64_t, int32_t> coarse_at;
  coarse_cells.clear();
  for (const auto& [i, j] : cells) {
    if (i % 2 == 0 && j % 2 == 0) {
      coarse_at.emplace(key(i / 2, j / 2), static_cast<int32_t>(coarse_cells.size()));
      coarse_cells.push_back({i / 2, j / 2});
    }
  }
  std::vector<Eigen::Triplet<double>> entries;
  for (size_t f = 0; f < cells.size(); ++f) {
    const auto [i, j] = cells[f];
    // The coarse parents along each axis: the point itself when even, both neighbours when odd.
    auto parents = [](int32_t x, int32_t out[2]) {
      if (x % 2 == 0) {
        out[0] = x / 2;
        return 1;
      }
      out[0] = (x - 1) / 2;
      out[1] = (x + 1) / 2;
      return 2;
    };
    int32_t pi[2], pj[2];
    const int ni = parents(i, pi), nj = parents(j, pj);
    const double weight = 1.0 / (ni * nj);
    for (int a = 0; a < ni; ++a) {
      for (int b = 0; b < nj; ++b) {
        const auto it = coarse_at.find(key(pi[a], pj[b]));
        if (it != coarse_at.end()) entries.emplace_back(static_cast<int>(f), it->second, weight);  // outside: the rim's zero
      }
    }
  }
  SparseMatrix P(static_cast<Eigen::Index>(cells.size()), static_cast<Eigen::Index>(coarse_cells.size()));
  P.setFromTriplets(entries.begin(), entries.end());
  return P;
}

// For each point, its place when the red points ((i + j) even) come first, then the black ones,
// each colour in the given order.
std::vector<int32_t> red_black_order(const std::vector<std::array<int32_t, 2>>& cells) {
  std::vector<int32_t> place(cells.size());
  int32_t next = 0;
  for (int colour = 0; colour < 2; ++colour) {
    for (size_t k = 0; k < cells.size(); ++k) {
      if (((cells[k][0] + cells[k][1]) & 1) == colour) place[k] = next++;
    }
  }
  return place;
}

// M with row r moved to row_place[r] and column c to column_place[c] (empty: unmoved).
SparseMatrix permuted(const SparseMatrix& m, const std::vector<int32_t>& row_place, const std::vector<int32_t>& column_place) {
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(static_cast<size_t>(m.nonZeros()));
  for (Eigen::Index c = 0; c < m.outerSize(); ++c) {
    for (SparseMatrix::InnerIterator it(m, c); it; ++it) {
      const auto r = static_cast<size_t>(it.row());
      entries.emplace_back(row_place.empty() ? it.row() : row_place[r], column_place.empty() ? c : column_place[static_cast<size_t>(c)],
                           it.value());
    }
  }
  SparseMatrix out(m.rows(), m.cols());
  out.setFromTriplets(entries.begin(), entries.end());
  return out;
}

}  // namespace

// A sparse matrix as rows of equal width (ELLPACK), a multiple of four entries: short rows are
// padded with zero entries that repeat the row's last column (so a non-finite value spreads no
// further than a real entry would). Every row of these matrices has 2 to 9 entries,
// so the padding costs little and the sweeps' inner loops unroll by four with no per-row bounds.
template <typename Value>
struct LatticeMultigrid::PaddedRows {
  int width = 0;
  std::vector<int32_t> column;
  std::vector<Value> value;

  // `m`'s entries, without the diagonal when `skip_diagonal`.
  PaddedRows(const RowMajorSparse& m, bool skip_diagonal) {
    for (Eigen::Index r = 0; r < m.outerSize(); ++r) {
      int count = 0;
      for (RowMajorSparse::InnerIterator it(m, r); it; ++it) count += !(skip_diagonal && it.col() == r);
      width = std::max(width, count);
    }
    width = (width + 3) / 4 * 4;
    column.assign(static_cast<size_t>(m.outerSize()) * static_cast<size_t>(width), 0);
    value.assign(column.size(), Value(0));
    for (Eigen::Index r = 0; r < m.outerSize(); ++r) {
      const size_t first = static_cast<size_t>(r) * static_cast<size_t>(width), end = first + static_cast<size_t>(width);
      size_t at = first;
      for (RowMajorSparse::InnerIterator it(m, r); it; ++it) {
        if (skip_diagonal && it.col() == r) continue;
        column[at] = static_cast<int32_t>(it.col());
        value[at++] = static_cast<Value>(it.value());
      }
      const int32_t pad = at > first ? column[at - 1] : static_cast<int32_t>(std::min<Eigen::Index>(r, m.cols() - 1));
      for (; at < end; ++at) column[at] = pad;
    }
  }
  PaddedRows() = default;
  size_t bytes() const { return column.size() * sizeof(int32_t) + value.size() * sizeof(Value); }

  // Σ_k value(r, k) u[column(r, k)].
  template <typename Point>
  Point row_sum(size_t r, const Point* u, Point zero) const {
    const int32_t* c = column.data() + r * static_cast<size_t>(width);
    const Value* v = value.data() + r * static_cast<size_t>(width);
    Point s = zero;
    for (int k = 0; k < width; k += 4) s += v[k] * u[c[k]] + v[k + 1] * u[c[k + 1]] + v[k + 2] * u[c[k + 2]] + v[k + 3] * u[c[k + 3]];
    return s;
  }
};

struct LatticeMultigrid::Level {
  PaddedRows<float> off_diagonal;  // the level's matrix without its diagonal
  std::vector<float> diagonal, inverse_diagonal;
  PaddedRows<float> prolongation;                               // from the next coarser level (a row per node of this level)
  PaddedRows<float> restriction;                                // to it (Pᵀ: a row per node of the coarser level)
  std::unique_ptr<Eigen::SimplicialLDLT<SparseMatrix>> direct;  // the coarsest level only
  // Work arrays: the right-hand side, iterate and residual of the level's correction equation.
  mutable std::vector<Float4> b, x, residual;

  size_t size() const { return diagonal.size(); }
  size_t bytes() const {
    return off_diagonal.bytes() + prolongation.bytes() + restriction.bytes() + (diagonal.size() + inverse_diagonal.size()) * sizeof(float) +
           (b.size() + x.size() + residual.size()) * sizeof(Float4);
  }

  void forward_sweep() const {
    for (size_t r = 0; r < size(); ++r) x[r] = (b[r] - off_diagonal.row_sum(r, x.data(), Float4{})) * inverse_diagonal[r];
  }
  void backward_sweep() const {
    for (size_t r = size(); r-- > 0;) x[r] = (b[r] - off_diagonal.row_sum(r, x.data(), Float4{})) * inverse_diagonal[r];
  }
  void compute_residual() const {
    for (size_t r = 0; r < size(); ++r) residual[r] = b[r] - diagonal[r] * x[r] - off_diagonal.row_sum(r, x.data(), Float4{});
  }
};

LatticeMultigrid::LatticeMultigrid(const SparseMatrix& K, const std::vector<std::array<int32_t, 2>>& cells) : n_(K.rows()) {
  if (K.rows() != K.cols() || static_cast<size_t>(K.rows()) != cells.size()) {
    throw Error(ErrorCode::kInvalidArgument, "multigrid: the matrix and the lattice points disagree in size");
  }
  fine_ = std::make_unique<PaddedRows<double>>(RowMajorSparse(K), /*skip_diagonal=*/true);
  fine_diagonal_ = K.diagonal();
  SparseMatrix A = K;
  std::vector<std::array<int32_t, 2>> level_cells = cells;
  SparseMatrix prolongation_above;  // the previous level's P, its columns in this level's order before colouring
  for (;;) {
    // Red points ((i + j) even) first, then black: on the 5-point stencil a colour's points depend
    // on the other colour only, so a sweep has no chain from one row to the next.
    const std::vector<int32_t> colour_order = red_black_order(level_cells);
    A = permuted(A, colour_order, colour_order);
    std::vector<std::array<int32_t, 2>> coloured_cells(level_cells.size());
    for (size_t k = 0; k < level_cells.size(); ++k) coloured_cells[static_cast<size_t>(colour_order[k])] = level_cells[k];
    level_cells = std::move(coloured_cells);
    if (levels_.empty()) {
      fine_order_ = colour_order;
    } else {
      Level& above = *levels_.back();
      const SparseMatrix P = permuted(prolongation_above, {}, colour_order);
      above.prolongation = PaddedRows<float>(RowMajorSparse(P), false);
      above.restriction = PaddedRows<float>(RowMajorSparse(SparseMatrix(P.transpose())), false);
    }

    auto level = std::make_unique<Level>();
    const auto n = static_cast<size_t>(A.rows());
    level->off_diagonal = PaddedRows<float>(RowMajorSparse(A), /*skip_diagonal=*/true);
    level->diagonal.resize(n);
    level->inverse_diagonal.resize(n);
    for (size_t r = 0; r < n; ++r) {
      const double d = A.coeff(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(r));
      if (!(d > 0)) throw Error(ErrorCode::kNumerical, "multigrid: a level's matrix has a non-positive diagonal");
      level->diagonal[r] = static_cast<float>(d);
      level->inverse_diagonal[r] = static_cast<float>(1.0 / d);
    }
    level->b.resize(n);
    level->x.resize(n);
    level->residual.resize(n);
    std::vector<std::array<int32_t, 2>> coarse_cells;
    const SparseMatrix P = A.rows() > kCoarsestSize ? bilinear_prolongation(level_cells, coarse_cells) : SparseMatrix();
    if (P.cols() == 0 || P.cols() >= A.rows()) {
      level->direct = std::make_unique<Eigen::SimplicialLDLT<SparseMatrix>>(A);
      if (level->direct->info() != Eigen::Success)
        throw Error(ErrorCode::kNumerical, "multigrid: the coarsest level could not be factored");
      levels_.push_back(std::move(level));
      break;
    }
    SparseMatrix coarse = (SparseMatrix(P.transpose()) * A * P).pruned();
    A = std::move(coarse);
    level_cells = std::move(coarse_cells);
    prolongation_above = P;
    levels_.push_back(std::move(level));
  }
}

LatticeMultigrid::~LatticeMultigrid() = default;

int LatticeMultigrid::levels() const { return static_cast<int>(levels_.size()); }

size_t LatticeMultigrid::bytes() const {
  size_t total = fine_->bytes() + static_cast<size_t>(fine_diagonal_.size()) * sizeof(double);
  for (const auto& level : levels_) total += level->bytes();
  return total;
}

double LatticeMultigrid::cycle(const Vec3* b, const Vec3* x, Vec3* out) const {
  // The residual in double precision (the terms of K x cancel to far less than x), the correction
  // in single: it is as small as the step, so single precision costs ~1e-7 of the step only.
  const Level& top = *levels_.front();
  double norm2 = 0;
  for (Eigen::Index r = 0; r < n_; ++r) {
    const Vec3 s = b[r] - fine_diagonal_[r] * x[r] - fine_->row_sum(static_cast<size_t>(r), x, Vec3(Vec3::Zero()));
    norm2 += s.squaredNorm();
    top.b[static_cast<size_t>(fine_order_[static_cast<size_t>(r)])] =
        Float4{static_cast<float>(s.x()), static_cast<float>(s.y()), static_cast<float>(s.z()), 0.0f};
  }
  std::fill(top.x.begin(), top.x.end(), Float4{});
  v_cycle(0);
  for (Eigen::Index r = 0; r < n_; ++r) {
    const Float4& e = top.x[static_cast<size_t>(fine_order_[static_cast<size_t>(r)])];
    out[r] = x[r] + Vec3(e[0], e[1], e[2]);
  }
  return std::sqrt(norm2);
}

int LatticeMultigrid::solve(const Vec3* b, Vec3* x, double relative_residual, int max_cycles) const {
  double b2 = 0;
  for (Eigen::Index r = 0; r < n_; ++r) b2 += b[r].squaredNorm();
  const double target = relative_residual * std::sqrt(b2);
  // A cycle reports the residual it started from: the one after cycle k is known in cycle k + 1.
  for (int cycles = 1; cycles <= max_cycles + 1; ++cycles) {
    if (cycle(b, x) <= target) return cycles - 1;  // (the cycle just run only improved x further)
  }
  return -1;
}

void LatticeMultigrid::v_cycle(size_t l) const {
  const Level& level = *levels_[l];
  const auto n = static_cast<Eigen::Index>(level.size());
  if (level.direct) {
    Eigen::MatrixXd rhs(n, 3);
    for (Eigen::Index r = 0; r < n; ++r) {
      for (int c = 0; c < 3; ++c) rhs(r, c) = level.b[static_cast<size_t>(r)][c];
    }
    const Eigen::MatrixXd u = level.direct->solve(rhs);
    for (Eigen::Index r = 0; r < n; ++r) {
      level.x[static_cast<size_t>(r)] = Float4{static_cast<float>(u(r, 0)), static_cast<float>(u(r, 1)), static_cast<float>(u(r, 2)), 0.0f};
    }
    return;
  }
  level.forward_sweep();
  level.compute_residual();
  const Level& coarse = *levels_[l + 1];
  for (size_t c = 0; c < coarse.size(); ++c) {
    coarse.b[c] = level.restriction.row_sum(c, level.residual.data(), Float4{});
    coarse.x[c] = Float4{};
  }
  v_cycle(l + 1);
  for (size_t r = 0; r < level.size(); ++r) level.x[r] += level.prolongation.row_sum(r, coarse.x.data(), Float4{});
  level.backward_sweep();
}

}  // namespace facemorph
