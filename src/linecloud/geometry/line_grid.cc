#include "linecloud/geometry/line_grid.h"

#include <algorithm>
#include <cmath>

#include "linecloud/util/error.h"
#include "linecloud/util/parallel.h"

namespace linecloud {
namespace {

// Distance of two centred lines (∞ when within the angle of parallel), with
// the sine of their angle.
double CrossingDistance(const PluckerLine& a, const PluckerLine& b, double* sin_angle) {
  const double s = a.v.cross(b.v).norm();
  *sin_angle = s;
  if (s == 0) return std::numeric_limits<double>::infinity();
  return std::abs(a.v.dot(b.w) + b.v.dot(a.w)) / s;
}

}  // namespace

Eigen::AlignedBox3d RobustBox(std::span<const Eigen::Vector3d> points, double low, double margin) {
  Eigen::AlignedBox3d box;
  if (points.empty()) return box;
  std::vector<double> c(points.size());
  for (int axis = 0; axis < 3; ++axis) {
    for (size_t i = 0; i < points.size(); ++i) c[i] = points[i][axis];
    // Quantile indices rounded to the nearest rank.
    const size_t last = c.size() - 1;
    const size_t lo = std::min(last, static_cast<size_t>(low * last + 0.5));
    const size_t hi = std::min(last, static_cast<size_t>((1 - low) * last + 0.5));
    std::nth_element(c.begin(), c.begin() + lo, c.end());
    box.min()[axis] = c[lo];
    std::nth_element(c.begin(), c.begin() + hi, c.end());
    box.max()[axis] = c[hi];
  }
  const double grow = margin * box.diagonal().norm();
  box.min().array() -= grow;
  box.max().array() += grow;
  return box;
}

LineGrid::LineGrid(std::span<const PluckerLine> lines, const Eigen::AlignedBox3d& box,
                   double radius, size_t max_entries, int max_cells_per_axis)
    : box_(box), radius_(radius) {
  if (!(radius > 0) || !std::isfinite(radius)) Fail("line grid: radius {} is not positive", radius);
  if (lines.size() >= (size_t{1} << 32)) Fail("line grid: {} lines are too many", lines.size());
  if (max_cells_per_axis < 1) Fail("line grid: {} cells per axis", max_cells_per_axis);
  if (box_.isEmpty()) return;
  centre_ = box_.center();
  const Eigen::Vector3d lo = box_.min() - centre_, hi = box_.max() - centre_;
  centred_.reserve(lines.size());
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> segments(lines.size());
  std::vector<bool> inside(lines.size(), false);
  double total_length = 0;
  const Eigen::Vector3d pad = Eigen::Vector3d::Constant(radius);
  for (size_t i = 0; i < lines.size(); ++i) {
    const PluckerLine& l = lines[i];
    centred_.emplace_back(l.v, l.w - centre_.cross(l.v));
    Eigen::Vector3d a, b;
    if (ClipToBox(centred_.back(), lo - pad, hi + pad, &a, &b)) {
      segments[i] = {a, b};
      inside[i] = true;
      total_length += (b - a).norm();
    }
  }
  const Eigen::Vector3d extent = box_.sizes();
  // At most 2^24 cells (their index costs 8 bytes each).
  cell_ = std::max({extent.maxCoeff() / max_cells_per_axis, std::cbrt(extent.prod() / (1 << 24)),
                    2.0 * total_length / static_cast<double>(std::max<size_t>(max_entries, 1)),
                    2.0 * radius});
  for (int k = 0; k < 3; ++k) {
    dims_[k] = std::max(1, static_cast<int>(std::ceil(extent[k] / cell_)));
  }
  // Two passes (count, then fill): no (cell, line) pairs held at once.
  const int64_t cells = static_cast<int64_t>(dims_[0]) * dims_[1] * dims_[2];
  starts_.assign(cells + 1, 0);
  std::vector<int64_t> near;
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<uint64_t> fill;
    if (pass == 1) {
      for (int64_t c = 0; c < cells; ++c) starts_[c + 1] += starts_[c];
      lines_.resize(starts_[cells]);
      fill.assign(starts_.begin(), starts_.end() - 1);
    }
    for (size_t i = 0; i < lines.size(); ++i) {
      if (!inside[i]) continue;
      CellsNearSegment(segments[i].first, segments[i].second, radius_, &near);
      for (const int64_t c : near) {
        if (pass == 0) {
          ++starts_[c + 1];
        } else {
          lines_[fill[c]++] = static_cast<uint32_t>(i);
        }
      }
    }
  }
}

int64_t LineGrid::CentredCellOf(const Eigen::Vector3d& centred) const {
  const Eigen::Vector3d rel = (centred - (box_.min() - centre_)) / cell_;
  int64_t index = 0;
  for (int k = 2; k >= 0; --k) {
    const double f = std::floor(rel[k]);
    if (!(f >= 0 && f < dims_[k])) return -1;
    index = index * dims_[k] + static_cast<int64_t>(f);
  }
  return index;
}

int64_t LineGrid::CellOf(const Eigen::Vector3d& x) const {
  if (lines_.empty() && centred_.empty()) return -1;
  return CentredCellOf(x - centre_);
}

void LineGrid::CellsOfBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                          std::vector<int64_t>* out) const {
  const Eigen::Vector3d origin = box_.min() - centre_;
  Eigen::Array3i from, to;
  for (int k = 0; k < 3; ++k) {
    const double f = std::floor((lo[k] - origin[k]) / cell_);
    const double t = std::floor((hi[k] - origin[k]) / cell_);
    if (!(t >= 0 && f < dims_[k])) return;  // (NaN fails too)
    from[k] = static_cast<int>(std::max(0.0, f));
    to[k] = static_cast<int>(std::min<double>(dims_[k] - 1, t));
  }
  for (int z = from[2]; z <= to[2]; ++z) {
    for (int y = from[1]; y <= to[1]; ++y) {
      for (int x = from[0]; x <= to[0]; ++x) {
        out->push_back((static_cast<int64_t>(z) * dims_[1] + y) * dims_[0] + x);
      }
    }
  }
}

void LineGrid::CellsNearSegment(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double reach,
                                std::vector<int64_t>* out) const {
  // Slab by slab of cells across the segment's longest axis k: a point of
  // slab g within `reach` of the segment is within reach of its piece whose
  // k lies within reach of the slab, and within reach of that piece's
  // bounding box on the other two axes. Each cell once.
  out->clear();
  const Eigen::Vector3d origin = box_.min() - centre_, d = b - a;
  int k = 0;
  d.cwiseAbs().maxCoeff(&k);
  const int k1 = (k + 1) % 3, k2 = (k + 2) % 3;
  const double lo = std::min(a[k], b[k]) - reach, hi = std::max(a[k], b[k]) + reach;
  const int g_from = std::max(0, static_cast<int>(std::floor((lo - origin[k]) / cell_)));
  const int g_to = std::min(dims_[k] - 1, static_cast<int>(std::floor((hi - origin[k]) / cell_)));
  Eigen::Array3i step;
  step[0] = 1, step[1] = dims_[0], step[2] = dims_[0] * dims_[1];
  for (int g = g_from; g <= g_to; ++g) {
    // The piece of the segment with k in the slab grown by reach.
    double t0 = 0, t1 = 1;
    if (d[k] != 0) {
      const double s0 = (origin[k] + g * cell_ - reach - a[k]) / d[k];
      const double s1 = (origin[k] + (g + 1) * cell_ + reach - a[k]) / d[k];
      t0 = std::max(0.0, std::min(s0, s1));
      t1 = std::min(1.0, std::max(s0, s1));
      if (t0 > t1) continue;
    }
    const Eigen::Vector3d p = a + d * t0, q = a + d * t1;
    int from[2], to[2];
    bool empty = false;
    for (int m = 0; m < 2; ++m) {
      const int axis = m == 0 ? k1 : k2;
      const double f = std::floor((std::min(p[axis], q[axis]) - reach - origin[axis]) / cell_);
      const double t = std::floor((std::max(p[axis], q[axis]) + reach - origin[axis]) / cell_);
      if (!(t >= 0 && f < dims_[axis])) empty = true;
      from[m] = static_cast<int>(std::max(0.0, f));
      to[m] = static_cast<int>(std::min<double>(dims_[axis] - 1, t));
    }
    if (empty) continue;
    for (int u = from[0]; u <= to[0]; ++u) {
      for (int v = from[1]; v <= to[1]; ++v) {
        out->push_back(static_cast<int64_t>(g) * step[k] + static_cast<int64_t>(u) * step[k1] +
                       static_cast<int64_t>(v) * step[k2]);
      }
    }
  }
}

void LineGrid::CellsNear(const Eigen::Vector3d& x, double r, std::vector<int64_t>* out) const {
  out->clear();
  if (centred_.empty()) return;
  const Eigen::Vector3d c = x - centre_, reach = Eigen::Vector3d::Constant(r);
  CellsOfBox(c - reach, c + reach, out);
}

void LineGrid::CellsNear(const PluckerLine& line, double r, std::vector<int64_t>* out) const {
  out->clear();
  if (centred_.empty()) return;
  const PluckerLine centred(line.v, line.w - centre_.cross(line.v));
  const Eigen::Vector3d pad = Eigen::Vector3d::Constant(r);
  Eigen::Vector3d a, b;
  if (!ClipToBox(centred, box_.min() - centre_ - pad, box_.max() - centre_ + pad, &a, &b)) return;
  CellsNearSegment(a, b, r, out);
}

void LineGrid::LinesNear(const Eigen::Vector3d& x, std::vector<uint32_t>* out) const {
  out->clear();
  if (lines_.empty() || !box_.contains(x)) return;  // the last cells reach past the box
  const Eigen::Vector3d xc = x - centre_;
  const int64_t c = CentredCellOf(xc);
  if (c < 0) return;
  for (const uint32_t i : LinesIn(c)) {
    if (centred_[i].DistanceTo(xc) <= radius_) out->push_back(i);
  }
}

void LineGrid::CrossingPairs(
    double min_angle_rad, std::span<const uint8_t> group,
    const std::function<void(uint32_t, uint32_t, const Eigen::Vector3d&, double)>& pair,
    int threads) const {
  if (!group.empty() && group.size() != centred_.size()) {
    Fail("line grid: {} group labels for {} lines", group.size(), centred_.size());
  }
  const double min_sin = std::sin(min_angle_rad);
  const Eigen::Vector3d lo = box_.min() - centre_, hi = box_.max() - centre_;  // box, centred
  struct Found {
    uint32_t i, j;
    Eigen::Vector3d mid;
    double d;
  };
  // Per thread: the cell's lines side by side in float, for a vectorised
  // first test of every pair (generous: float's rounding never drops a pair
  // the exact test below keeps; near-parallel pairs always go on to it).
  struct Local {
    std::vector<float> v[3], w[3], q[3], d2;
  };
  std::vector<Local> locals(WorkerThreads(threads));
  const float r2 = static_cast<float>(1.1 * radius_ * 1.1 * radius_);
  const auto pairs_of_cell = [&](int64_t c, Local& l, std::vector<Found>* out) {
    const std::span<const uint32_t> in_cell = LinesIn(c);
    const size_t o = in_cell.size();
    for (int k = 0; k < 3; ++k) l.v[k].resize(o), l.w[k].resize(o), l.q[k].resize(o);
    l.d2.resize(o);
    for (size_t m = 0; m < o; ++m) {
      const PluckerLine& x = centred_[in_cell[m]];
      const Eigen::Vector3d anchor = x.v.cross(x.w) / x.v.squaredNorm();
      for (int k = 0; k < 3; ++k) {
        l.v[k][m] = static_cast<float>(x.v[k]);
        l.w[k][m] = static_cast<float>(x.w[k]);
        l.q[k][m] = static_cast<float>(anchor[k]);
      }
    }
    // The cell's extent in cells (centred frame), grown by a slack (in
    // cells) that float's rounding of the midpoint never crosses.
    const Eigen::Vector3d cell_lo(static_cast<double>(c % dims_[0]),
                                  static_cast<double>((c / dims_[0]) % dims_[1]),
                                  static_cast<double>(c / (int64_t{dims_[0]} * dims_[1])));
    const Eigen::Vector3d origin = box_.min() - centre_;
    const double inv_cell = 1.0 / cell_, slack = 1e-2;
    const float* __restrict VX = l.v[0].data();
    const float* __restrict VY = l.v[1].data();
    const float* __restrict VZ = l.v[2].data();
    const float* __restrict WX = l.w[0].data();
    const float* __restrict WY = l.w[1].data();
    const float* __restrict WZ = l.w[2].data();
    float* __restrict d2 = l.d2.data();
    for (size_t p = 0; p + 1 < o; ++p) {
      const float vx = VX[p], vy = VY[p], vz = VZ[p], wx = WX[p], wy = WY[p], wz = WZ[p];
      const float vv = vx * vx + vy * vy + vz * vz;
      for (size_t q = p + 1; q < o; ++q) {
        const float c = vx * VX[q] + vy * VY[q] + vz * VZ[q];
        const float s2 = vv * (VX[q] * VX[q] + VY[q] * VY[q] + VZ[q] * VZ[q]) - c * c;
        const float num =
            vx * WX[q] + vy * WY[q] + vz * WZ[q] + VX[q] * wx + VY[q] * wy + VZ[q] * wz;
        d2[q] = s2 > 1e-6f * vv ? num * num / s2 : 0.f;
      }
      const uint32_t i = in_cell[p];
      for (size_t q = p + 1; q < o; ++q) {
        if (!(d2[q] <= r2)) continue;
        const uint32_t j = in_cell[q];
        if (!group.empty() && group[i] == group[j]) continue;
        {
          // The midpoint in float first: most pairs within the radius belong
          // to another cell (the two lines share several).
          const float c2 = vx * VX[q] + vy * VY[q] + vz * VZ[q];
          const float vq = VX[q] * VX[q] + VY[q] * VY[q] + VZ[q] * VZ[q];
          const float den = vv * vq - c2 * c2;
          // Only where float's error is far below the slack: lines at least
          // ~6° apart (the error grows as 1 / sin² of their angle).
          if (den > 1e-2f * vv * vq) {
            const float rx = l.q[0][q] - l.q[0][p], ry = l.q[1][q] - l.q[1][p],
                        rz = l.q[2][q] - l.q[2][p];
            const float rp = rx * vx + ry * vy + rz * vz, rq = rx * VX[q] + ry * VY[q] + rz * VZ[q];
            const float tp = (rp * vq - c2 * rq) / den, tq = (c2 * rp - vv * rq) / den;
            const Eigen::Vector3d mid(0.5 * (l.q[0][p] + tp * vx + l.q[0][q] + tq * VX[q]),
                                      0.5 * (l.q[1][p] + tp * vy + l.q[1][q] + tq * VY[q]),
                                      0.5 * (l.q[2][p] + tp * vz + l.q[2][q] + tq * VZ[q]));
            const Eigen::Vector3d f = (mid - origin) * inv_cell - cell_lo;
            if ((f.array() < -slack).any() || (f.array() > 1 + slack).any()) continue;
          }
        }
        double sin_angle = 0;
        const double d = CrossingDistance(centred_[i], centred_[j], &sin_angle);
        if (!(d <= radius_) || sin_angle < min_sin) continue;
        Eigen::Vector3d pi, pj;
        if (!ClosestPoints(centred_[i], centred_[j], &pi, &pj)) continue;
        const Eigen::Vector3d mid = 0.5 * (pi + pj);
        if (CentredCellOf(mid) != c) continue;  // another cell reports it
        // The last cell of an axis reaches past the box: crossings there are outside it.
        if ((mid.array() < lo.array()).any() || (mid.array() > hi.array()).any()) continue;
        // In the box in centred coordinates; adding the centre back may round an ulp past it.
        out->push_back({i, j, (mid + centre_).cwiseMax(box_.min()).cwiseMin(box_.max()), d});
      }
    }
  };
  // Blocks of cells searched in parallel, reported in cell order.
  constexpr int64_t kBlock = 1024;
  std::vector<std::vector<Found>> found(kBlock);
  for (int64_t first = 0; first < num_cells(); first += kBlock) {
    const int64_t count = std::min(kBlock, num_cells() - first);
    ParallelFor(static_cast<size_t>(count), threads, [&](size_t b, int worker) {
      found[b].clear();
      pairs_of_cell(first + static_cast<int64_t>(b), locals[worker], &found[b]);
    });
    for (int64_t b = 0; b < count; ++b) {
      for (const Found& f : found[b]) pair(f.i, f.j, f.mid, f.d);
    }
  }
}

}  // namespace linecloud
