// The rotation taking one pair of non-parallel vectors onto another (the
// TRIAD construction): frames F(a1, a2) = [e1, e3 × e1, e3] with e1 = â1,
// e3 = (a1 × a2)^ are built on both sides and R = F_b F_aᵀ. Exact when the
// two pairs are related by a rotation; used by the point-point solvers.
#pragma once

#include <Eigen/Core>

namespace linecloud {

// False when either pair is (nearly) parallel or not finite.
inline bool OrthonormalFrame(const Eigen::Vector3d& a1, const Eigen::Vector3d& a2,
                             Eigen::Matrix3d* frame) {
  const Eigen::Vector3d n = a1.cross(a2);
  const double n_norm = n.norm(), a1_norm = a1.norm();
  if (!(n_norm > 1e-12 * a1_norm * a2.norm()) || !(a1_norm > 0) || !std::isfinite(n_norm)) {
    return false;
  }
  const Eigen::Vector3d e1 = a1 / a1_norm;
  const Eigen::Vector3d e3 = n / n_norm;
  frame->col(0) = e1;
  frame->col(1) = e3.cross(e1);
  frame->col(2) = e3;
  return true;
}

inline bool TriadRotation(const Eigen::Vector3d& a1, const Eigen::Vector3d& a2,
                          const Eigen::Vector3d& b1, const Eigen::Vector3d& b2,
                          Eigen::Matrix3d* b_from_a) {
  Eigen::Matrix3d fa, fb;
  if (!OrthonormalFrame(a1, a2, &fa) || !OrthonormalFrame(b1, b2, &fb)) return false;
  *b_from_a = fb * fa.transpose();
  return true;
}

}  // namespace linecloud
