#pragma once

#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// p3P: absolute pose of a calibrated camera from 3 bearings and 3 points
// (the paper's own solver is Haralick et al. 1994). Find R, t with
//     λ_i f_i = R X_i + t,  λ_i > 0,   i = 1, 2, 3.
// The depths satisfy λ_i² + λ_j² − 2 (f_i·f_j) λ_i λ_j = |X_i − X_j|²; with the
// longest side between points 2 and 3 and its length as the unit, the scale
// drops out of two of them: two homogeneous conics in Λ = (λ1, λ2, λ3) with the
// side ratios a, b ≤ 1 as coefficients (Ding, Yang, Kukelova, "Revisiting the
// P3P Problem", CVPR 2023). A degenerate member of their pencil (one real root
// of a cubic with closed-form coefficients — whenever real solutions exist,
// every real degenerate member is a pair of real planes, as in Persson &
// Nordberg, "Lambda Twist", ECCV 2018) is split into its two planes through
// its adjugate; each plane cuts a conic in at most 2 rays, a quadratic in a
// depth ratio, giving up to 4 solutions, refined by Newton steps. When the
// cubic has a single real root, the two real solutions share one plane and the
// other is skipped. R = Y X⁻¹ with X, Y the triangles' edge frames
// [x12, x13, x12 × x13] in world and camera, t = λ1 f1 − R X1.
int p3p(std::span<const Eigen::Vector3d> bearings, std::span<const Eigen::Vector3d> points,
        std::vector<Rigid3d>* out);

}  // namespace linecloud
