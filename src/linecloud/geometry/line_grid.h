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
// Cost: a line enters about 1.5 × (box extent / cell) cells (those its
// segment crosses, and those within `radius` of it); the cell size is chosen
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
  // `radius` > 0 is the largest distance LinesNear and CrossingPairs ask
  // about. The cell is at least extent / `max_cells_per_axis`, at least
  // 2 × radius, and large enough that the entries stay near `max_entries`
  // (4 bytes each).
  LineGrid(std::span<const PluckerLine> lines, const Eigen::AlignedBox3d& box, double radius,
           size_t max_entries = size_t{1} << 25, int max_cells_per_axis = 128);

  // Indices of the lines passing within `radius` of `x` (exact distances).
  // Nothing for a point outside the box.
  void LinesNear(const Eigen::Vector3d& x, std::vector<uint32_t>* out) const;

  // Calls `pair(i, j, midpoint, distance)` once for every pair i < j of lines
  // passing within `radius` of each other, not within `min_angle_rad` of
  // parallel, whose closest points' midpoint lies inside the box. When
  // `group` is given, only pairs with group[i] != group[j] are reported
  // (e.g. lines of two maps). Cells are visited on `threads` threads (0: all
  // cores); `pair` is called from one thread at a time, in cell order.
  void CrossingPairs(
      double min_angle_rad, std::span<const uint8_t> group,
      const std::function<void(uint32_t, uint32_t, const Eigen::Vector3d&, double)>& pair,
      int threads = 1) const;

  // The building blocks of searches with radii of their own (the density
  // attack's nearest lines and points). Every line is entered in every cell
  // it passes through (and in those within `radius` of it), so:
  //   - a line within r of a point x passes through a cell of CellsNear(x, r);
  //   - the point of line j closest to line i, when the two pass within r of
  //     each other inside the box, lies in a cell of CellsNear(line i, r), and
  //     line j is listed in that cell: testing CellOf(that point) == cell
  //     visits each such j exactly once.
  // Cells are indices in [0, num_cells()); -1: outside the grid. Points and
  // lines in world coordinates; `out` without repeats.
  int64_t CellOf(const Eigen::Vector3d& x) const;
  void CellsNear(const Eigen::Vector3d& x, double r, std::vector<int64_t>* out) const;
  void CellsNear(const PluckerLine& line, double r, std::vector<int64_t>* out) const;
  std::span<const uint32_t> LinesIn(int64_t cell) const {
    return {lines_.data() + starts_[cell], lines_.data() + starts_[cell + 1]};
  }
  int64_t num_cells() const { return static_cast<int64_t>(starts_.size()) - 1; }
  // The grid's corner (world) and cells per axis: cell c = x + dims.x * (y +
  // dims.y * z) spans corner + (x, y, z) * cell() onwards.
  Eigen::Vector3d corner() const { return box_.min(); }
  const Eigen::AlignedBox3d& box() const { return box_; }
  Eigen::Array3i dims() const { return dims_; }

  double cell() const { return cell_; }
  size_t entries() const { return lines_.size(); }

 private:
  int64_t CentredCellOf(const Eigen::Vector3d& centred) const;
  // Cells meeting the box [lo, hi] (centred), appended.
  void CellsOfBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                  std::vector<int64_t>* out) const;
  // Cells within `reach` of the centred segment a–b (a superset), each once.
  void CellsNearSegment(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double reach,
                        std::vector<int64_t>* out) const;

  std::vector<PluckerLine> centred_;  // the lines relative to the box's centre
  Eigen::Vector3d centre_ = Eigen::Vector3d::Zero();
  Eigen::AlignedBox3d box_;
  double radius_ = 0;
  double cell_ = 0;
  Eigen::Array3i dims_ = Eigen::Array3i::Ones();
  // The lines of cell c are lines_[starts_[c] .. starts_[c + 1]), in index order.
  std::vector<uint32_t> lines_;
  std::vector<uint64_t> starts_ = {0, 0};
};

// The box spanned per axis by the `low` and 1 − `low` quantiles of the points,
// grown by `margin` times its diagonal on every side (SfM's stray points left
// out). Empty points: an empty box.
Eigen::AlignedBox3d RobustBox(std::span<const Eigen::Vector3d> points, double low = 0.005,
                              double margin = 0.05);

}  // namespace linecloud
