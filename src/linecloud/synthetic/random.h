// Seeded random geometry for synthetic data.
#pragma once

#include <random>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace linecloud {

// Uniform on SO(3) (normalised Gaussian quaternion).
inline Eigen::Quaterniond RandomRotation(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized();
}

// Uniform on the unit sphere.
inline Eigen::Vector3d RandomUnit(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
}

}  // namespace linecloud
