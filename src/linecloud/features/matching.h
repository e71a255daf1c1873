// Matching query descriptors to a map's descriptors: the two nearest
// neighbours of each query descriptor by descriptor angle, Lowe's ratio test
// (Lowe, IJCV 2004) and COLMAP's absolute distance test, with COLMAP's default
// thresholds; optionally a mutual (cross) check.
//
// Exact search: the dot products of all pairs as one float matrix product per
// block of query rows (Eigen). The descriptors are bytes, so every product is
// an integer below 2²⁴ and exact in float.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <vector>

namespace linecloud {

struct DescriptorMatchOptions {
  double max_ratio = 0.8;     // best / second-best descriptor angle (COLMAP: max_ratio)
  double max_distance = 0.7;  // best descriptor angle, radians of the 512-normalised bytes
  bool cross_check = false;   // also the query descriptor must be the map descriptor's best
  int dim = 128;

  void Check() const;
};

struct DescriptorMatch {
  int query = 0;    // row of the query descriptors
  int map = 0;      // row of the map descriptors
  float ratio = 0;  // best / second-best angle: lower is more distinctive (a match score)
};

// The angle between two descriptors of 512-normalised bytes from their dot
// product (COLMAP's descriptor distance).
float DescriptorAngle(float dot);

// The tests a match passes, from the dot products of the query descriptor
// with its best and second-best map descriptors: best angle ≤ max_distance
// and < max_ratio × second angle (">=" rejects a tie, as COLMAP). The match,
// with its ratio as score, or nothing.
std::optional<DescriptorMatch> TestMatch(int query, int map, float best_dot, float second_dot,
                                         const DescriptorMatchOptions& options);

// `query` and `map` are row-major byte matrices of `options.dim` columns.
// `progress(done, total)` is called between blocks of query rows when given.
std::vector<DescriptorMatch> MatchDescriptors(
    std::span<const uint8_t> query, std::span<const uint8_t> map,
    const DescriptorMatchOptions& options,
    const std::function<void(size_t, size_t)>& progress = nullptr);

}  // namespace linecloud
