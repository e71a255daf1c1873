#pragma once

#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// m-p2P+u: generalized absolute pose with known gravity, 2 correspondences
// (the problem of Sweeney, Fragoso, Höllerer, Turk, "Efficient computation of
// absolute pose for gravity-aware augmented reality", ISMAR 2015; this
// elimination is our own).
//
// Find R = R_y(θ), t with, for i = 1, 2 (ray i: origin o_i, direction d_i,
// both in the rig frame):
//     R X_i + t = o_i + λ_i d_i        (λ_i of any sign)
// Subtracting the two removes t; the component of the difference along
// d₁ × d₂ removes λ₁, λ₂ and leaves one line α c + β s + γ = 0 on the unit
// circle (c = cos θ, s = sin θ): up to 2 solutions, each meeting both rays
// exactly (λ₁ by a cross product, then t). rig_from_world.
int m_p2p_u(std::span<const Eigen::Vector3d> origins, std::span<const Eigen::Vector3d> directions,
            std::span<const Eigen::Vector3d> points, std::vector<Rigid3d>* out);

// The same solutions as (cos θ, sin θ, t), for callers that build another pose
// from them; returns how many (0–2).
struct UprightSolution {
  double c, s;
  Eigen::Vector3d t;
};
int m_p2p_u(std::span<const Eigen::Vector3d> origins, std::span<const Eigen::Vector3d> directions,
            std::span<const Eigen::Vector3d> points, UprightSolution solutions[2]);

}  // namespace linecloud
