// `linecloud eval prepare`: the paper's protocol (Speciale et al., CVPR 2019,
// Sec. 5) on a real dataset, up to the correspondences every method shares.
#pragma once

#include <cstdint>
#include <string>

#include "linecloud/eval/eval_work.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/mapping/sfm.h"

namespace linecloud {

struct EvalPrepareOptions {
  std::string dataset_dir;
  std::string work_dir;
  SfmOptions sfm;  // the reconstruction of all images (mapping/sfm.h)
  // +u without an IMU: gravity = the ground-truth vertical rotated by a random
  // angle ~ |N(0, σ)| about a random horizontal axis, σ in degrees.
  double gravity_noise_deg = 0.2;
  uint64_t seed = 1;

  void Check() const;
};

// Runs (or reuses) COLMAP, builds every group's map and correspondences and
// writes WORK/prepared.json; returns what it wrote.
EvalWork PrepareEvaluation(const EvalPrepareOptions& options);

// The map of a query group: `full` without the images named in `group`, and
// without the points that keep fewer than two observations; each remaining
// point re-optimised (reprojection error, Huber loss) with the poses fixed.
Reconstruction MapWithoutImages(const Reconstruction& full, const std::vector<std::string>& group);

// Gauss–Newton on the reprojection error of one point with fixed cameras;
// returns false (and leaves `point` as it was) when it does not lower the cost.
struct PointObservation {
  const Camera* camera;
  Rigid3d cam_from_world;
  Eigen::Vector2d xy;
};
bool RefinePointFixedPoses(const std::vector<PointObservation>& observations,
                           Eigen::Vector3d* point);

}  // namespace linecloud
