#include "linecloud/features/matching.h"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <limits>

#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using FloatRows = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

FloatRows ToFloat(std::span<const uint8_t> bytes, int dim) {
  const Eigen::Index rows = static_cast<Eigen::Index>(bytes.size() / dim);
  FloatRows m(rows, dim);
  for (Eigen::Index r = 0; r < rows; ++r) {
    for (int c = 0; c < dim; ++c) m(r, c) = bytes[r * dim + c];
  }
  return m;
}

}  // namespace

float DescriptorAngle(float dot) {
  constexpr float kNorm = 1.0f / (512.0f * 512.0f);
  return std::acos(std::min(kNorm * dot, 1.0f));
}

std::optional<DescriptorMatch> TestMatch(int query, int map, float best_dot, float second_dot,
                                         const DescriptorMatchOptions& options) {
  const float best_angle = DescriptorAngle(best_dot);
  const float second_angle = DescriptorAngle(std::max(second_dot, 0.0f));
  if (best_angle > options.max_distance || best_angle >= options.max_ratio * second_angle) {
    return std::nullopt;
  }
  return DescriptorMatch{query, map, second_angle > 0 ? best_angle / second_angle : 1.0f};
}

void DescriptorMatchOptions::Check() const {
  if (!(max_ratio > 0 && max_ratio <= 1))
    Fail("matching: max_ratio must be in (0, 1], got {}", max_ratio);
  if (!(max_distance > 0)) Fail("matching: max_distance must be positive, got {}", max_distance);
  if (dim <= 0) Fail("matching: descriptor dimension must be positive, got {}", dim);
}

std::vector<DescriptorMatch> MatchDescriptors(std::span<const uint8_t> query,
                                              std::span<const uint8_t> map,
                                              const DescriptorMatchOptions& options,
                                              const std::function<void(size_t, size_t)>& progress) {
  options.Check();
  const int dim = options.dim;
  if (query.size() % dim != 0 || map.size() % dim != 0) {
    Fail("matching: descriptor blocks of {} and {} bytes are not multiples of {}", query.size(),
         map.size(), dim);
  }
  const size_t nq = query.size() / dim, nm = map.size() / dim;
  std::vector<DescriptorMatch> matches;
  if (nq == 0 || nm < 2) return matches;
  const FloatRows m = ToFloat(map, dim);
  // For the cross check: each map row's best query row.
  std::vector<float> map_best(options.cross_check ? nm : 0, -1.0f);
  std::vector<int> map_best_query(options.cross_check ? nm : 0, -1);
  std::vector<DescriptorMatch> candidates;
  constexpr size_t kBlock = 256;
  for (size_t start = 0; start < nq; start += kBlock) {
    const size_t rows = std::min(kBlock, nq - start);
    const FloatRows q = ToFloat(query.subspan(start * dim, rows * dim), dim);
    const FloatRows dots = q * m.transpose();  // rows x nm
    for (size_t r = 0; r < rows; ++r) {
      float best = -1, second = -1;
      int best_j = -1;
      for (size_t j = 0; j < nm; ++j) {
        const float d = dots(r, j);
        if (d > best) {
          second = best;
          best = d;
          best_j = static_cast<int>(j);
        } else if (d > second) {
          second = d;
        }
        if (options.cross_check && d > map_best[j]) {
          map_best[j] = d;
          map_best_query[j] = static_cast<int>(start + r);
        }
      }
      if (const auto m = TestMatch(static_cast<int>(start + r), best_j, best, second, options)) {
        candidates.push_back(*m);
      }
    }
    if (progress) progress(start + rows, nq);
  }
  for (const DescriptorMatch& c : candidates) {
    if (!options.cross_check || map_best_query[c.map] == c.query) matches.push_back(c);
  }
  return matches;
}

}  // namespace linecloud
