// k-nearest-neighbour searches between lines and points for the attacks of
// privacy/: exact by brute force over all pairs (vectorised float32
// distances, several threads), or through a grid of the scene's box
// (NeighbourGrid below) for clouds too large for n². A line's distance to
// another line or to a point is not a metric on a fixed-dimensional point set
// that a kd-tree (nanoflann, FLANN) or an inner-product index (FAISS) could
// search; a grid of cells each line passes through is what applies.
//
// Distances (unit directions v, anchors q, moments w = q × v, all relative to
// the set's centre):
//   line–line   d² = (v_i·w_j + v_j·w_i)² / (1 − (v_i·v_j)²)   (∞ when the lines
//               are within ~0.6° of parallel: they have no crossing to vote with)
//   point–line  d² = |X − q|² − ((X − q)·v)²
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/line_grid.h"
#include "linecloud/geometry/plucker.h"

namespace linecloud {

// Lines and points in float32 structure-of-arrays form, relative to `centre`
// (the searches lose no precision on scenes far from the origin).
struct LineArrays {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> v, q;  // double: unit directions, anchors (centred)
  std::vector<float> vx, vy, vz, qx, qy, qz, wx, wy, wz;
  size_t size() const { return v.size(); }
};
LineArrays MakeLineArrays(std::span<const PluckerLine> lines, const Eigen::Vector3d& centre);

struct PointArrays {
  std::vector<float> x, y, z;  // centred
  size_t size() const { return x.size(); }
};
PointArrays MakePointArrays(std::span<const Eigen::Vector3d> centred_points);

// Squared distances from row i to every element of the other set, written to
// d2 (size of the other set).
void LineToLinesSq(const LineArrays& lines, size_t i, float* d2);
// Line i of `from` to every line of `to` (both relative to the same centre);
// pairs with 1 − cos² ≤ min_sin_sq get ∞.
void LineToLinesSq(const LineArrays& from, size_t i, const LineArrays& to, float* d2,
                   float min_sin_sq);
void LineToPointsSq(const LineArrays& lines, size_t i, const PointArrays& points, float* d2);
void PointToLinesSq(const PointArrays& points, size_t i, const LineArrays& lines, float* d2);

// Reusable buffers of one thread for SmallestK.
struct SelectBuffers {
  std::vector<float> sample;
  std::vector<uint32_t> candidates;
};

// The indices of the k smallest finite values of d2 (fewer if fewer are
// finite), in no particular order. Linear time: a threshold from a strided
// sample, a branch-free gather below it, a selection among the survivors.
void SmallestK(std::span<const float> d2, size_t k, SelectBuffers* buffers,
               std::vector<uint32_t>* out);

// The same searches through a LineGrid of the lines (in the arrays' centred
// frame) over `box` (centred too), for pairs meeting inside the box: the
// line–line search compares the pairs of each cell once (closest points'
// midpoint in the cell, both lines listed there), the point searches visit
// the cells near the query. Exact within the radius asked; a line whose k-th
// neighbour lies beyond it gets fewer than k.
class NeighbourGrid {
 public:
  // `pair_radius`: the line–line radius of CoarseVotes (the grid holds each
  // line in the cells within half of it).
  NeighbourGrid(const LineArrays& lines, const Eigen::AlignedBox3d& centred_box, double pair_radius,
                size_t max_entries);

  // Per-thread buffers of the point queries.
  struct Buffers {
    std::vector<int64_t> cells;
    std::vector<uint32_t> ids;
    std::vector<float> d2;
    std::vector<uint32_t> stamp;  // dedup of lines met in several cells
    uint32_t epoch = 0;
    SelectBuffers select;
    std::vector<uint32_t> picked;
  };

  // For every line i, the parameters along it of its points closest to the
  // lines passing within the pair radius of it (not within ~0.6° of
  // parallel): the k nearest, to 1/32 of the radius (all lines of the
  // distance bin holding the k-th are kept). votes[starts[i] .. starts[i+1]).
  // A line with more than 4k + 64 pairs up to its k-th's bin (lines
  // crowding through one spot, e.g. a crafted map) keeps none: `exact[i]`,
  // its k nearest are then to be searched over every line. Memory stays
  // O(n k) whatever the map.
  struct LineVotes {
    std::vector<uint64_t> starts;
    std::vector<float> t;
    std::vector<uint8_t> exact;
    size_t short_of_k = 0;  // lines with fewer than k within the radius
  };
  // `each_cell` (optional) is called before each cell's pairs, from the
  // worker threads (e.g. a time budget that throws).
  LineVotes CoarseVotes(size_t k, int threads,
                        const std::function<void()>& each_cell = nullptr) const;

  // Points (centred) to search next, kept by reference: point i is line i's
  // estimate, which the two searches below leave out (as LineToPointsSq's
  // callers do by hand).
  void SetPoints(const PointArrays* points);
  // The ≤ k points nearest to line i within r, other than point i.
  void NearestPoints(size_t i, size_t k, double r, Buffers* b, std::vector<uint32_t>* out) const;
  // The ≤ k lines nearest to point i within r, other than line i.
  void NearestLinesToPoint(size_t i, size_t k, double r, Buffers* b,
                           std::vector<uint32_t>* out) const;

  const LineGrid& grid() const { return grid_; }

 private:
  static std::vector<PluckerLine> Lines(const LineArrays& a);
  // The pairs of lines of a cell within the pair radius whose closest
  // points' midpoint lies in the cell: for each, an event at either end (the
  // line's place in the cell, the distance's bin, the parameter along it),
  // handed to `flush` ordered by line, in batches of at most ~2^20.
  struct PairEnd {
    uint32_t line;  // in the cell's list
    uint32_t bin;
    float t;
  };
  struct CellScratch {
    std::vector<float> rows;
    std::vector<PairEnd> ends, sorted;
    std::vector<uint32_t> starts;
  };
  void PairsOfCell(int64_t cell, int bins, CellScratch* s,
                   const std::function<void(const CellScratch&)>& flush) const;
  void Pick(size_t k, Buffers* b, std::vector<uint32_t>* out) const;

  const LineArrays& a_;
  double pair_radius_ = 0;
  LineGrid grid_;
  // Copies side by side (one cache line's read per candidate): lines' v, q;
  // points by cell (CSR) with their coordinates in that order.
  struct LineRow {
    float v[3], q[3], pad[2];
  };
  struct PointRow {
    float x[3];
    uint32_t id;
  };
  std::vector<LineRow> rows_;
  std::vector<uint32_t> point_starts_;
  std::vector<PointRow> points_by_cell_;
  const PointArrays* points_ = nullptr;
};

// The radius within which `quantile` of `samples` evenly spaced rows find
// their k nearest: d2s(row, d2) fills the row's squared distances to the
// other set (`other_size` of them; ∞ or NaN: never a neighbour). On
// `threads` threads (0: all cores). 0 when no sampled row has a neighbour.
double SampledRadius(size_t rows, size_t k, double quantile, size_t samples,
                     const std::function<void(size_t, float*)>& d2s, size_t other_size,
                     int threads);

}  // namespace linecloud
