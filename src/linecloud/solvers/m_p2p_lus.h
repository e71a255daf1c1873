#pragma once

#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// m-P2P+l+u+s: rigid alignment with known gravity from 2 point pairs (Horn,
// JOSA A 1987, restricted to rotations about y). Find R = R_y(θ), t with
//     X̃_i = R X_i + t,   i = 1, 2.
// With d = X_2 − X_1 and e = X̃_2 − X̃_1, R_y(θ) acts on (d_z + i d_x) as
// multiplication by e^{iθ}, so θ = arg(e_z + i e_x) − arg(d_z + i d_x).
// One solution (none when d is vertical), local_from_world.
int m_p2p_lus(std::span<const Eigen::Vector3d> points_local,
              std::span<const Eigen::Vector3d> points, std::vector<Rigid3d>* out);

// The rotation R = R_y(θ) and translation t of X̃_i = scale · R X_i + t for a
// given scale (θ does not depend on it); false for a degenerate sample.
bool UprightTwoPointAlignment(std::span<const Eigen::Vector3d> points_local,
                              std::span<const Eigen::Vector3d> points, double scale,
                              Eigen::Quaterniond* rotation, Eigen::Vector3d* translation);

}  // namespace linecloud
