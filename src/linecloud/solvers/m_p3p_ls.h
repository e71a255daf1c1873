#pragma once

#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// m-P3P+l+s: rigid alignment of 3 local (metric) points to 3 map points
// (Horn, "Closed-form solution of absolute orientation using unit
// quaternions", JOSA A 1987; the minimal case solved in closed form by the
// TRIAD construction). Find R, t with
//     X̃_i = R X_i + t,   i = 1, 2, 3.
// One solution (none for collinear points), local_from_world.
int m_p3p_ls(std::span<const Eigen::Vector3d> points_local, std::span<const Eigen::Vector3d> points,
             std::vector<Rigid3d>* out);

}  // namespace linecloud
