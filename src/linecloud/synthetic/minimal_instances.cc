#include "linecloud/synthetic/minimal_instances.h"

#include <cmath>
#include <numbers>

#include "linecloud/synthetic/random.h"

namespace linecloud {

std::string_view FamilyName(InstanceFamily family) {
  switch (family) {
    case InstanceFamily::kGeneric:
      return "generic";
    case InstanceFamily::kNarrowFov:
      return "10° FOV";
    case InstanceFamily::kLinesAlongRays:
      return "lines ~1° from rays";
    case InstanceFamily::kLinesThroughPoint:
      return "lines through 1 point";
  }
  return "?";
}

MinimalInstance RandomMinimalInstance(const MethodInfo& m, std::mt19937_64& rng,
                                      InstanceFamily family, int num_correspondences) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  MinimalInstance inst;
  Sim3d& truth = inst.truth;
  if (m.gravity) {
    const double theta = std::numbers::pi * u(rng);
    truth.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitY()));
  } else {
    truth.rotation = RandomRotation(rng);
  }
  truth.translation = Eigen::Vector3d(g(rng), g(rng), g(rng));
  truth.scale = m.similarity() ? std::pow(10.0, u(rng)) : 1.0;
  const Sim3d world_from_query = truth.Inverse();
  MinimalSample& s = inst.sample;
  const int n = num_correspondences > 0 && !m.local_points ? num_correspondences : m.sample_size;

  if (m.local_points) {
    // X̃ spread around the query frame; X the corresponding map point.
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector3d x_local(2 * u(rng), 2 * u(rng), 4.0 + 2 * u(rng));
      const Eigen::Vector3d x = world_from_query * x_local;
      s.points_local.push_back(x_local);
      if (m.lines) {
        s.lines.push_back(PluckerLine::FromPointAndDirection(x, RandomUnit(rng)));
      } else {
        s.points.push_back(x);
      }
    }
    return inst;
  }

  // Bearing methods: one camera, or a rig of up to 4 randomly placed cameras.
  const int num_cameras = m.multi ? std::min(n, 4) : 1;
  for (int c = 0; c < num_cameras; ++c) {
    if (m.multi) {
      s.cam_from_rig.emplace_back(RandomRotation(rng),
                                  Eigen::Vector3d(g(rng), g(rng), g(rng)) * 0.5);
    }
  }
  const Rigid3d rig_from_world(truth.rotation, truth.translation);
  // Half-width of the image plane at unit depth: ~90° or 10° field of view.
  const double half_width =
      family == InstanceFamily::kNarrowFov ? std::tan(5.0 * std::numbers::pi / 180) : 1.0;
  Eigen::Vector3d common_point = Eigen::Vector3d::Zero();
  if (family == InstanceFamily::kLinesThroughPoint) {  // no draw otherwise: same stream
    common_point = world_from_query * Eigen::Vector3d(g(rng), g(rng), 6.0);
  }
  for (int i = 0; i < n; ++i) {
    const int c = m.multi ? (i < num_cameras ? i : static_cast<int>(rng() % num_cameras)) : 0;
    const Rigid3d cam_from_world = m.multi ? s.cam_from_rig[c] * rig_from_world : rig_from_world;
    // A point in front of the camera within a ~90° field of view.
    const Eigen::Vector3d x_cam = Eigen::Vector3d(half_width * u(rng), half_width * u(rng), 1.0) *
                                  (2.0 + 8.0 * 0.5 * (1.0 + u(rng)));
    const Eigen::Vector3d x = cam_from_world.Inverse() * x_cam;
    s.bearings.push_back(x_cam.normalized());
    if (m.multi) s.camera_index.push_back(c);
    if (m.lines) {
      Eigen::Vector3d direction = RandomUnit(rng);
      if (family == InstanceFamily::kLinesAlongRays) {
        // The viewing ray's direction in the world, tilted by ~1°.
        direction = (x - cam_from_world.Center()).normalized() + 0.0175 * RandomUnit(rng);
      } else if (family == InstanceFamily::kLinesThroughPoint) {
        direction = x - common_point;
      }
      s.lines.push_back(PluckerLine::FromPointAndDirection(x, direction));
    } else {
      s.points.push_back(x);
    }
  }
  return inst;
}

PoseError ComparePoses(const Sim3d& estimate, const Sim3d& truth) {
  PoseError e;
  e.rotation_rad = estimate.rotation.angularDistance(truth.rotation);
  e.translation_rel =
      (estimate.translation - truth.translation).norm() / std::max(1.0, truth.translation.norm());
  e.scale_rel = std::abs(estimate.scale - truth.scale) / truth.scale;
  return e;
}

}  // namespace linecloud
