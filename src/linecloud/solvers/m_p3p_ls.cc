#include "linecloud/solvers/m_p3p_ls.h"

#include "linecloud/util/check.h"

#include "linecloud/solvers/triad.h"

namespace linecloud {

int m_p3p_ls(std::span<const Eigen::Vector3d> points_local, std::span<const Eigen::Vector3d> points,
             std::vector<Rigid3d>* out) {
  CheckMinimalSample("m_p3p_ls", 3, out, points_local, points);
  out->clear();
  // Frames on the triangle's centroid-relative edges; the longest-edge choice
  // does not matter for exact data, the centroid keeps t well conditioned.
  Eigen::Matrix3d r;
  if (!TriadRotation(points[1] - points[0], points[2] - points[0],
                     points_local[1] - points_local[0], points_local[2] - points_local[0], &r)) {
    return 0;
  }
  const Eigen::Vector3d centroid = (points[0] + points[1] + points[2]) / 3.0;
  const Eigen::Vector3d centroid_local =
      (points_local[0] + points_local[1] + points_local[2]) / 3.0;
  const Eigen::Vector3d t = centroid_local - r * centroid;
  if (!t.allFinite()) return 0;
  out->emplace_back(Eigen::Quaterniond(r), t);
  return 1;
}

}  // namespace linecloud
