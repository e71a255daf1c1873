#pragma once

#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// m-P3P+l: similarity alignment of 3 local points (unknown scale) to 3 map
// points (Umeyama, "Least-squares estimation of transformation parameters
// between two point patterns", TPAMI 1991; minimal case in closed form).
// Find s > 0, R, t with
//     X̃_i = s R X_i + t,   i = 1, 2, 3.
// s is the ratio of the triangles' edge lengths (root of summed squares), R
// the TRIAD rotation. One solution (none for collinear points).
int m_p3p_l(std::span<const Eigen::Vector3d> points_local, std::span<const Eigen::Vector3d> points,
            std::vector<Sim3d>* out);

}  // namespace linecloud
