// Helpers for the known-gravity (+u) solvers: after pre-alignment gravity
// points along −y in both frames, so the unknown rotation is about y:
//   R_y(θ) = [ c 0 s ; 0 1 0 ; −s 0 c ],  c = cos θ, s = sin θ.
// For a vector X, R_y X = c·A(X) + s·B(X) + D(X) with
//   A(X) = (X_x, 0, X_z),  B(X) = (X_z, 0, −X_x),  D(X) = (0, X_y, 0),
// which makes every +u constraint linear in (c, s).
#pragma once

#include <cmath>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace linecloud::upright {

inline Eigen::Vector3d A(const Eigen::Vector3d& x) { return {x.x(), 0.0, x.z()}; }
inline Eigen::Vector3d B(const Eigen::Vector3d& x) { return {x.z(), 0.0, -x.x()}; }
inline Eigen::Vector3d D(const Eigen::Vector3d& x) { return {0.0, x.y(), 0.0}; }

inline Eigen::Quaterniond RotationY(double c, double s) {
  // Unit quaternion of the rotation with (cos θ, sin θ) ∝ (c, s) (any positive
  // scale). With r = |(c, s)|, (cos θ/2, sin θ/2) ∝ (r + c, s) ∝ (s, r − c):
  // the form without cancellation is taken, then normalised (two square roots).
  const double r = std::sqrt(c * c + s * s);
  double w = c >= 0 ? r + c : s, y = c >= 0 ? s : r - c;
  if (w < 0) {
    w = -w;
    y = -y;
  }
  const double inv = 1 / std::sqrt(w * w + y * y);
  return Eigen::Quaterniond(w * inv, 0.0, y * inv, 0.0);
}

// The same for (c, s) already on the unit circle (to rounding): the half
// angle from cos θ = 1 − 2 sin²(θ/2) = 2 cos²(θ/2) − 1 takes one square root;
// the form without cancellation is taken.
inline Eigen::Quaterniond RotationYUnit(double c, double s) {
  if (c >= 0) {
    const double w = std::sqrt(0.5 * (1 + c));
    return Eigen::Quaterniond(w, 0.0, s / (2 * w), 0.0);
  }
  const double y = std::copysign(std::sqrt(0.5 * (1 - c)), s);
  return Eigen::Quaterniond(s / (2 * y), 0.0, y, 0.0);
}

// Orthonormal u1, u2 spanning the plane orthogonal to a non-zero d.
inline void OrthogonalBasis(const Eigen::Vector3d& d, Eigen::Vector3d* u1, Eigen::Vector3d* u2) {
  Eigen::Index axis;
  d.cwiseAbs().minCoeff(&axis);
  *u1 = d.cross(Eigen::Vector3d::Unit(axis)).normalized();
  *u2 = d.cross(*u1).normalized();
}

// Real (c, s) on the unit circle with α c + β s + γ = 0; returns how many (0–2).
inline int IntersectLineUnitCircle(double alpha, double beta, double gamma, double cs[2][2]) {
  const double r2 = alpha * alpha + beta * beta;
  if (!(r2 > 1e-300) || !std::isfinite(r2) || !std::isfinite(gamma)) return 0;
  const double disc = r2 - gamma * gamma;
  if (disc < 0) return 0;
  const double c0 = -gamma * alpha / r2, s0 = -gamma * beta / r2;
  const double h = std::sqrt(disc) / r2;
  cs[0][0] = c0 - h * beta;
  cs[0][1] = s0 + h * alpha;
  cs[1][0] = c0 + h * beta;
  cs[1][1] = s0 - h * alpha;
  return disc == 0 ? 1 : 2;
}

}  // namespace linecloud::upright
