#pragma once

#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// p2P+u: absolute pose of one camera with known gravity from 2 bearings
// (Sweeney, Fragoso, Höllerer, Turk, ISMAR 2015). Find R = R_y(θ), t with
//     λ_i f_i = R X_i + t,   i = 1, 2.
// The central case of m_p2p_u (all rays through the origin): up to 2
// solutions, cam_from_world. Inputs are gravity-aligned (see METHODS.md).
int p2p_u(std::span<const Eigen::Vector3d> bearings, std::span<const Eigen::Vector3d> points,
          std::vector<Rigid3d>* out);

}  // namespace linecloud
