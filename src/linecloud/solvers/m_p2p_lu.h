#pragma once

#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// m-P2P+l+u: similarity alignment with known gravity from 2 point pairs
// (Umeyama, TPAMI 1991, restricted to rotations about y). Find s > 0,
// R = R_y(θ), t with
//     X̃_i = s R X_i + t,   i = 1, 2.
// s = |X̃_2 − X̃_1| / |X_2 − X_1|, θ as in m_p2p_lus. One solution.
int m_p2p_lu(std::span<const Eigen::Vector3d> points_local, std::span<const Eigen::Vector3d> points,
             std::vector<Sim3d>* out);

}  // namespace linecloud
