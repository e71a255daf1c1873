// What `linecloud eval prepare` leaves in its work directory and `eval run`
// reads: per query group its map (a COLMAP model without the group's images),
// ground truth, the 2D–3D correspondences found by indirect matching, the
// group's local structure and rig, and gravity. Stored as WORK/prepared.json
// plus one COLMAP binary model per group.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "linecloud/geometry/camera.h"
#include "linecloud/geometry/rigid3.h"

namespace linecloud {

struct EvalCorrespondence {
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();  // pixels
  uint64_t point_id = 0;                         // map point (and line) id
  int votes = 0;                                 // map-image matches that agree
  // +l: the keypoint's point in the group's own reconstruction, rig frame,
  // metric; absent when the local reconstruction did not triangulate it.
  std::optional<Eigen::Vector3d> point_local;
};

struct EvalImage {
  std::string name;
  uint32_t camera_id = 0;
  Rigid3d cam_from_world;                             // ground truth (full reconstruction)
  Rigid3d cam_from_rig;                               // valid when the group has a rig
  Eigen::Vector3d gravity = Eigen::Vector3d::Zero();  // unit, camera frame
  std::vector<EvalCorrespondence> correspondences;
};

struct EvalGroup {
  std::string name;     // g00, g01, ...
  std::string map_dir;  // relative to the work directory
  std::vector<EvalImage> images;
  bool has_rig = false;    // cam_from_rig and local points are valid
  std::string rig_source;  // "calibration" or "local reconstruction"
  Rigid3d rig_from_world;  // ground truth
  Eigen::Vector3d gravity_rig = Eigen::Vector3d::Zero();
  // The +l points without known scale are the metric ones times this factor
  // (the local reconstruction's own scale); the rig's translations too.
  double local_scale = 1.0;
  int map_points = 0;
};

struct EvalWork {
  std::string dataset;
  std::string dataset_dir;
  std::string units;  // "metres" or "reconstruction units"
  std::map<uint32_t, Camera> cameras;
  Eigen::Vector3d gravity_world = Eigen::Vector3d::Zero();
  std::string gravity_source;
  double gravity_noise_deg = 0;
  nlohmann::json reconstruction;  // statistics and the ground-truth comparison
  std::vector<EvalGroup> groups;
};

// A group's rig as a method poses it: metric, or for the methods that
// estimate scale (+s) in the local reconstruction's own scale (local_scale),
// which also scales their local points.
struct PosedRig {
  double scale = 1.0;
  std::vector<Rigid3d> cam_from_rig;  // one per image of the group
  Sim3d rig_from_world;               // the truth, in that scale
};
PosedRig PoseRig(const EvalGroup& g, bool similarity);

nlohmann::json EvalWorkToJson(const EvalWork& work);
// Throws Error naming `source` and the field on malformed input.
EvalWork EvalWorkFromJson(const nlohmann::json& j, const std::string& source);

}  // namespace linecloud
