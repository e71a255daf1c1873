// Exact k-nearest-neighbour searches between lines and points, by brute force
// over all pairs (vectorised float32 distances, several threads), for the
// attacks of privacy/. No spatial index applies: a line's distance to another
// line or to a point is not a metric on a fixed-dimensional point set that a
// kd-tree (nanoflann, FLANN) or an inner-product index (FAISS) could search.
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

}  // namespace linecloud
