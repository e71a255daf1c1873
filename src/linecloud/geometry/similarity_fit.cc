#include "linecloud/geometry/similarity_fit.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <Eigen/Geometry>

namespace linecloud {
namespace {

Sim3d FitIndexed(std::span<const Eigen::Vector3d> src, std::span<const Eigen::Vector3d> dst,
                 std::span<const uint32_t> idx) {
  Eigen::Matrix3Xd a(3, idx.size()), b(3, idx.size());
  for (size_t k = 0; k < idx.size(); ++k) {
    a.col(k) = src[idx[k]];
    b.col(k) = dst[idx[k]];
  }
  const Eigen::Matrix4d m = Eigen::umeyama(a, b, true);
  const Eigen::Matrix3d sr = m.topLeftCorner<3, 3>();
  const double s = std::cbrt(sr.determinant());
  if (!(s > 0) || !std::isfinite(s) || !m.allFinite())
    return Sim3d(0.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero());
  return Sim3d(s, Eigen::Quaterniond(sr / s).normalized(), m.topRightCorner<3, 1>());
}

}  // namespace

Sim3d FitSimilarity(std::span<const Eigen::Vector3d> src, std::span<const Eigen::Vector3d> dst) {
  std::vector<uint32_t> all(std::min(src.size(), dst.size()));
  for (size_t k = 0; k < all.size(); ++k) all[k] = static_cast<uint32_t>(k);
  if (all.size() < 3) return Sim3d(0.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero());
  return FitIndexed(src, dst, all);
}

RobustSimilarityFit FitSimilarityRobust(std::span<const Eigen::Vector3d> src,
                                        std::span<const Eigen::Vector3d> dst, double tolerance,
                                        int iterations, uint64_t seed) {
  RobustSimilarityFit best;
  const size_t n = std::min(src.size(), dst.size());
  if (n < 3) return best;
  const auto inliers_of = [&](const Sim3d& t) {
    std::vector<uint32_t> in;
    if (!(t.scale > 0)) return in;
    for (size_t k = 0; k < n; ++k) {
      if ((t * src[k] - dst[k]).norm() <= tolerance) in.push_back(static_cast<uint32_t>(k));
    }
    return in;
  };
  std::vector<uint32_t> all(n);
  for (size_t k = 0; k < n; ++k) all[k] = static_cast<uint32_t>(k);
  best.dst_from_src = FitIndexed(src, dst, all);
  best.inliers = inliers_of(best.dst_from_src);
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<size_t> pick(0, n - 1);
  for (int iter = 0; iter < iterations && best.inliers.size() < n; ++iter) {
    uint32_t sample[3];
    for (int k = 0; k < 3; ++k) sample[k] = static_cast<uint32_t>(pick(rng));
    if (sample[0] == sample[1] || sample[1] == sample[2] || sample[0] == sample[2]) continue;
    const Sim3d t = FitIndexed(src, dst, sample);
    if (!(t.scale > 0)) continue;
    std::vector<uint32_t> in = inliers_of(t);
    if (in.size() > best.inliers.size()) {
      best.dst_from_src = t;
      best.inliers = std::move(in);
    }
  }
  // Refitted on the inliers until they stop changing (at most a few times).
  for (int round = 0; round < 5 && best.inliers.size() >= 3; ++round) {
    const Sim3d t = FitIndexed(src, dst, best.inliers);
    if (!(t.scale > 0)) break;
    std::vector<uint32_t> in = inliers_of(t);
    const bool same = in == best.inliers;
    if (in.size() < best.inliers.size()) break;
    best.dst_from_src = t;
    best.inliers = std::move(in);
    if (same) break;
  }
  return best;
}

}  // namespace linecloud
