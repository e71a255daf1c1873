// A spatial index of lines: each line, clipped to a box, is entered in the
// cells of a uniform grid that lie within `radius` of it (conservatively: a
// cell may hold a line passing a little farther). It answers, without the
// O(N²) of comparing every pair:
//   - which lines pass within `radius` of a point (inside the box);
//   - which pairs of lines pass within `radius` of each other at a point
//     inside the box, each pair once (the cell of the midpoint of the two
//     closest points reports it).
// Used by the lifting (which released lines pass where a new point is) and by
// the crossing attacks of privacy/ (which lines meet).
//
// Cost: a line enters about (box extent / cell) cells; the cell size is chosen
// so that the entries stay near `max_entries`.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "linecloud/geometry/plucker.h"

namespace linecloud {

class LineGrid {
 public:
  // `radius` > 0 is the largest distance the
  // queries ask about. `max_cells_per_axis` bounds the resolution.
  LineGrid(std::span<const PluckerLine> lines, const Eigen::AlignedBox3d& box, double radius,
           size_t max_entries = size_t{1} << 25, int max_cells_per_axis = 128);

  // Indices of the lines passing within `radius` of `x` (exact distances).
  // Nothing for a point outside the box.
  void LinesNear(const Eigen::Vector3d& x, std::vector<uint32_t>* out) const;

  // Calls `pair(i, j, midpoint, distance)` once for every pair i < j of lines
  // passing within `radius` of each other, not within `min_angle_rad` of
  // parallel, whose closest points' midpoint lies inside the box. When
  // `group` is given, only pairs with group[i] != group[j] are reported
  // (e.g. lines of two maps).
  void CrossingPairs(
      double min_angle_rad, std::span<const uint8_t> group,
      const std::function<void(uint32_t, uint32_t, const Eigen::Vector3d&, double)>& pair) const;

  double cell() const { return cell_; }
  size_t entries() const { return entries_.size(); }

 private:
  int64_t CellOf(const Eigen::Vector3d& x) const;  // -1 outside the grid
  void CellsNear(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                 std::vector<int64_t>* out) const;

  std::vector<PluckerLine> centred_;  // the lines relative to the box's centre
  Eigen::Vector3d centre_ = Eigen::Vector3d::Zero();
  Eigen::AlignedBox3d box_;
  double radius_ = 0;
  double cell_ = 0;
  Eigen::Array3i dims_ = Eigen::Array3i::Ones();
  // (cell << 32 | line), sorted; `starts_` indexes the first entry of each
  // occupied cell in `cells_` order.
  std::vector<uint64_t> entries_;
  std::vector<int64_t> cells_;
  std::vector<size_t> starts_;
};

// The box spanned per axis by the `low` and 1 − `low` quantiles of the points,
// grown by `margin` times its diagonal on every side (SfM's stray points left
// out). Empty points: an empty box.
Eigen::AlignedBox3d RobustBox(std::span<const Eigen::Vector3d> points, double low = 0.005,
                              double margin = 0.05);

}  // namespace linecloud
