// Seeded synthetic localization queries for any of the 16 methods: a rig of
// 1–3 distorted cameras (one for single-image methods), observations with
// pixel noise and a chosen share of outliers, local 3D points (+l) in the
// rig frame of a Sim3 (unknown scale) or SE3 (+s) query frame, gravity in
// both frames (+u), and both maps — points and the lines lifted from them.
#pragma once

#include <random>

#include "linecloud/localize/localize.h"

namespace linecloud {

struct LocalizationInstanceOptions {
  int num_correspondences = 500;
  double inlier_ratio = 0.7;
  double noise_px = 1.0;       // std. dev. of the pixel noise of inliers
  double local_noise = 0.005;  // std. dev. of +l points, relative to depth
  int num_rig_cameras = 3;     // for m- methods
  double scene_depth = 10.0;   // points at depths in [0.2, 1] × scene_depth
  // Each observation gets a match ratio drawn from the histograms measured on
  // real photos (match_scores.h), for progressive sampling.
  bool match_scores = false;

  void Check() const;
};

struct LocalizationInstance {
  Query query;
  PointMap point_map;
  LineMap line_map;             // the point map lifted with random directions
  Sim3d truth;                  // query_from_world
  std::vector<char> is_inlier;  // per observation
  double scene_size = 0;        // for relative translation errors
};

LocalizationInstance RandomLocalizationInstance(const MethodInfo& method,
                                                const LocalizationInstanceOptions& options,
                                                std::mt19937_64& rng);

// Rotation error (rad) and error of the query frame's origin in the world
// (world units) between two query_from_world poses.
struct LocalizationError {
  double rotation_rad = 0;
  double position = 0;
};
LocalizationError CompareLocalization(const Sim3d& estimate, const Sim3d& truth);

}  // namespace linecloud
