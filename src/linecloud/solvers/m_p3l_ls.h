#pragma once

#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/plucker.h"
#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// m-P3L+l+s: local 3D points (metric) against 3 map lines (Lee et al., 2016
// in Speciale et al., CVPR 2019, Table 1: the generalized 3-point problem with
// map and query swapped). Find R, t with
//     X̃_i = R (v_i × w_i + α_i v_i) + t,   i = 1, 2, 3.
// world_from_local moves X̃_i onto line i: m_p3p with the lines as rays and
// X̃ as the points, then inverted. Up to 8 solutions, local_from_world.
int m_p3l_ls(std::span<const PluckerLine> lines, std::span<const Eigen::Vector3d> points_local,
             std::vector<Rigid3d>* out);

}  // namespace linecloud
