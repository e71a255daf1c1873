// A seeded synthetic indoor scene for the demo and for tests: points on the
// walls, floor, ceiling and furniture of a room, map images and query images
// from a realistic camera, and noisy 2D observations. World frame: y is up,
// gravity points along −y.
#pragma once

#include <cstdint>
#include <vector>

#include "linecloud/geometry/camera.h"
#include "linecloud/geometry/rigid3.h"
#include "linecloud/io/colmap_model.h"

namespace linecloud {

struct SyntheticSceneOptions {
  uint64_t seed = 42;
  int num_points = 4000;
  int num_map_images = 30;
  int num_queries = 20;
  double noise_px = 1.0;  // std. dev. of the 2D observation noise
  Eigen::Vector3d room_size = Eigen::Vector3d(10.0, 3.0, 7.0);  // x, y(up), z
  // SIMPLE_RADIAL camera: width, height, f, k (cx, cy at the centre).
  int width = 1024;
  int height = 768;
  double focal = 880.0;
  double radial_k = -0.03;

  void Check() const;  // throws Error on an invalid option
};

struct SyntheticObservation {
  Eigen::Vector2d xy;
  uint64_t point3D_id = 0;
};

struct SyntheticQuery {
  std::string name;
  Camera camera;
  Rigid3d cam_from_world;  // ground truth
  std::vector<SyntheticObservation> observations;
  Eigen::Vector3d gravity_in_cam;  // unit, camera frame
};

struct SyntheticScene {
  Reconstruction model;  // map images, points with tracks of >= 2 images
  std::vector<SyntheticQuery> queries;
  Eigen::Vector3d gravity_in_world = -Eigen::Vector3d::UnitY();
  double extent = 0;  // diagonal of the room
};

SyntheticScene GenerateSyntheticScene(const SyntheticSceneOptions& options);

}  // namespace linecloud
