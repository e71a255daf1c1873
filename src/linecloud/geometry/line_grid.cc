#include "linecloud/geometry/line_grid.h"

#include <algorithm>
#include <cmath>

#include "linecloud/util/error.h"

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
  cell_ = std::max({extent.maxCoeff() / max_cells_per_axis,
                    4.0 * total_length / static_cast<double>(std::max<size_t>(max_entries, 1)),
                    2.0 * radius});
  for (int k = 0; k < 3; ++k) {
    dims_[k] = std::max(1, static_cast<int>(std::ceil(extent[k] / cell_)));
  }
  std::vector<int64_t> cells;
  for (size_t i = 0; i < lines.size(); ++i) {
    if (!inside[i]) continue;
    cells.clear();
    CellsNear(segments[i].first, segments[i].second, &cells);
    for (const int64_t c : cells) entries_.push_back((static_cast<uint64_t>(c) << 32) | i);
  }
  std::sort(entries_.begin(), entries_.end());
  for (size_t k = 0; k < entries_.size(); ++k) {
    const int64_t c = static_cast<int64_t>(entries_[k] >> 32);
    if (cells_.empty() || cells_.back() != c) {
      cells_.push_back(c);
      starts_.push_back(k);
    }
  }
  starts_.push_back(entries_.size());
}

int64_t LineGrid::CellOf(const Eigen::Vector3d& centred) const {
  const Eigen::Vector3d rel = (centred - (box_.min() - centre_)) / cell_;
  int64_t index = 0;
  for (int k = 2; k >= 0; --k) {
    const double f = std::floor(rel[k]);
    if (!(f >= 0 && f < dims_[k])) return -1;
    index = index * dims_[k] + static_cast<int64_t>(f);
  }
  return index;
}

void LineGrid::CellsNear(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                         std::vector<int64_t>* out) const {
  // Samples every quarter cell: every point within `radius` of the segment is
  // within radius + cell / 8 of a sample, whose box of cells is entered.
  const double length = (b - a).norm();
  const int steps = std::max(1, static_cast<int>(std::ceil(length / (0.25 * cell_))));
  const double reach = radius_ + 0.125 * cell_;
  const Eigen::Vector3d origin = box_.min() - centre_;
  for (int s = 0; s <= steps; ++s) {
    const Eigen::Vector3d p = a + (b - a) * (static_cast<double>(s) / steps);
    Eigen::Array3i from, to;
    for (int k = 0; k < 3; ++k) {
      from[k] = std::max(0, static_cast<int>(std::floor((p[k] - reach - origin[k]) / cell_)));
      to[k] =
          std::min(dims_[k] - 1, static_cast<int>(std::floor((p[k] + reach - origin[k]) / cell_)));
    }
    for (int z = from[2]; z <= to[2]; ++z) {
      for (int y = from[1]; y <= to[1]; ++y) {
        for (int x = from[0]; x <= to[0]; ++x) {
          const int64_t c = (static_cast<int64_t>(z) * dims_[1] + y) * dims_[0] + x;
          if (out->empty() || out->back() != c) out->push_back(c);
        }
      }
    }
  }
  std::sort(out->begin(), out->end());
  out->erase(std::unique(out->begin(), out->end()), out->end());
}

void LineGrid::LinesNear(const Eigen::Vector3d& x, std::vector<uint32_t>* out) const {
  out->clear();
  if (cells_.empty() || !box_.contains(x)) return;  // the last cells reach past the box
  const Eigen::Vector3d xc = x - centre_;
  const int64_t c = CellOf(xc);
  if (c < 0) return;
  const auto it = std::lower_bound(cells_.begin(), cells_.end(), c);
  if (it == cells_.end() || *it != c) return;
  const size_t k = it - cells_.begin();
  for (size_t e = starts_[k]; e < starts_[k + 1]; ++e) {
    const uint32_t i = static_cast<uint32_t>(entries_[e]);
    if (centred_[i].DistanceTo(xc) <= radius_) out->push_back(i);
  }
}

void LineGrid::CrossingPairs(
    double min_angle_rad, std::span<const uint8_t> group,
    const std::function<void(uint32_t, uint32_t, const Eigen::Vector3d&, double)>& pair) const {
  if (!group.empty() && group.size() != centred_.size()) {
    Fail("line grid: {} group labels for {} lines", group.size(), centred_.size());
  }
  const double min_sin = std::sin(min_angle_rad);
  const Eigen::Vector3d lo = box_.min() - centre_, hi = box_.max() - centre_;  // box, centred
  std::vector<uint32_t> in_cell;
  for (size_t k = 0; k < cells_.size(); ++k) {
    in_cell.clear();
    for (size_t e = starts_[k]; e < starts_[k + 1]; ++e)
      in_cell.push_back(static_cast<uint32_t>(entries_[e]));
    for (size_t p = 0; p < in_cell.size(); ++p) {
      const uint32_t i = in_cell[p];
      for (size_t q = p + 1; q < in_cell.size(); ++q) {
        const uint32_t j = in_cell[q];
        if (!group.empty() && group[i] == group[j]) continue;
        double sin_angle = 0;
        const double d = CrossingDistance(centred_[i], centred_[j], &sin_angle);
        if (!(d <= radius_) || sin_angle < min_sin) continue;
        Eigen::Vector3d pi, pj;
        if (!ClosestPoints(centred_[i], centred_[j], &pi, &pj)) continue;
        const Eigen::Vector3d mid = 0.5 * (pi + pj);
        if (CellOf(mid) != cells_[k]) continue;  // another cell reports it
        // The last cell of an axis reaches past the box: crossings there are outside it.
        if ((mid.array() < lo.array()).any() || (mid.array() > hi.array()).any()) continue;
        // In the box in centred coordinates; adding the centre back may round an ulp past it.
        const Eigen::Vector3d world = (mid + centre_).cwiseMax(box_.min()).cwiseMin(box_.max());
        pair(std::min(i, j), std::max(i, j), world, d);
      }
    }
  }
}

}  // namespace linecloud
