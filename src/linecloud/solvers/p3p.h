#pragma once

#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// p3P: absolute pose of a calibrated camera from 3 bearings and 3 points,
// following Persson & Nordberg, "Lambda Twist: An Accurate Fast Robust
// Perspective Three Point (P3P) Solver", ECCV 2018 (the paper's own solver is
// Haralick et al. 1994; this formulation is faster and more accurate).
// Find R, t with
//     λ_i f_i = R X_i + t,  λ_i > 0,   i = 1, 2, 3.
// The depths satisfy λ_i² + λ_j² − 2 (f_i·f_j) λ_i λ_j = |X_i − X_j|², two
// homogeneous conics in Λ = (λ1, λ2, λ3). A degenerate member D1 + γ D2 of
// their pencil (γ: one real root of a cubic — whenever real solutions exist,
// every real degenerate member is a pair of real planes) is split into its two
// planes through its adjugate; each plane cuts the conics in at most 2 rays,
// giving up to 4 solutions, refined by Newton steps. R = Y X⁻¹ with X, Y the
// triangles' edge frames [x01, x02, x01 × x02] in world and camera (X⁻¹ is
// computed once per call), t = λ1 f1 − R X1.
int p3p(std::span<const Eigen::Vector3d> bearings,
        std::span<const Eigen::Vector3d> points, std::vector<Rigid3d>* out);

}  // namespace linecloud
