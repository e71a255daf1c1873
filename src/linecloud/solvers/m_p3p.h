#pragma once

#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// m-p3P: generalized absolute pose from 3 rays of a calibrated rig (the
// problem of Lee, Li, Pollefeys, "Minimal solutions for pose estimation of a
// multi-camera system", ISRR 2013 / Nistér & Stewénius, "A minimal solution to
// the generalised 3-point pose problem", JMIV 2007). Find R, t with
//     R X_i + t = o_i + λ_i d_i,   i = 1, 2, 3   (ray i in the rig frame)
// Unknown depths λ_i satisfy the three distance equations
//     |o_i − o_j + λ_i d_i − λ_j d_j|² = |X_i − X_j|²;
// eliminating λ3 (resultant of two quadratics) and then λ2 (reduction modulo
// the third equation) gives one polynomial of degree 8 in λ1. Depths of any
// sign are kept unless `positive_depths` (cheirality on the camera side, for
// point maps); never for line clouds, where the rays are unoriented lines.
// Each real root gives R, t by the TRIAD construction. rig_from_world.
int m_p3p(std::span<const Eigen::Vector3d> origins, std::span<const Eigen::Vector3d> directions,
          std::span<const Eigen::Vector3d> points, std::vector<Rigid3d>* out,
          bool positive_depths = true);

}  // namespace linecloud
