// Seeded dense surface samples, for the privacy attacks' tests and benchmark:
// a façade like the Strecha scenes (a wall with protruding blocks, columns and
// a dome, seen from one side), sampled uniformly by area.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace linecloud {

struct FacadeOptions {
  uint64_t seed = 7;
  int num_points = 20000;
  double width = 10.0, height = 6.0;  // metres; relief up to ~1.5 m deep
  // SfM points gather where the surface has texture: this share of the points
  // falls around `texture_spots` seeded spots (Gaussian, `spot_sigma` of the
  // patch's size); the rest is uniform by area.
  double texture_share = 0.0;
  int texture_spots = 400;
  double spot_sigma = 0.01;

  void Check() const;  // throws Error on an invalid option
};

// Points on the façade's surfaces (z is the wall's normal, towards the viewer).
std::vector<Eigen::Vector3d> SampleFacade(const FacadeOptions& options);

}  // namespace linecloud
