#include "linecloud/synthetic/localization_instances.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "linecloud/synthetic/match_scores.h"
#include "linecloud/synthetic/random.h"
#include "linecloud/util/error.h"

namespace linecloud {

void LocalizationInstanceOptions::Check() const {
  if (num_correspondences < 1) Fail("synthetic query: need at least one correspondence");
  if (!(inlier_ratio > 0 && inlier_ratio <= 1)) Fail("synthetic query: inlier ratio in (0, 1]");
  if (!(noise_px >= 0) || !(local_noise >= 0)) Fail("synthetic query: noise must be >= 0");
  if (num_rig_cameras < 1) Fail("synthetic query: need at least one rig camera");
  if (!(scene_depth > 0)) Fail("synthetic query: scene depth must be > 0");
}

LocalizationInstance RandomLocalizationInstance(const MethodInfo& method,
                                                const LocalizationInstanceOptions& options,
                                                std::mt19937_64& rng) {
  options.Check();
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  LocalizationInstance inst;
  Query& q = inst.query;

  // Query frame: Sim3 for +l without known scale, otherwise SE3.
  Sim3d& truth = inst.truth;
  truth.rotation = RandomRotation(rng);
  truth.translation = options.scene_depth * 0.5 * Eigen::Vector3d(g(rng), g(rng), g(rng));
  truth.scale = method.similarity() ? std::exp(std::log(10.0) * (2 * u(rng) - 1)) : 1.0;
  const Sim3d world_from_query = truth.Inverse();
  const Eigen::Vector3d gravity_world = RandomUnit(rng);
  q.gravity_map = gravity_world;
  q.gravity_query = truth.rotation * gravity_world;
  // Query-frame lengths are world lengths × s.
  const double s = truth.scale;

  const int num_cameras = method.multi ? options.num_rig_cameras : 1;
  for (int c = 0; c < num_cameras; ++c) {
    Camera camera;
    camera.model_id = CameraModelId::kSimpleRadial;
    camera.width = 800;
    camera.height = 600;
    camera.params = {600.0 + 100 * u(rng), 400.0, 300.0, -0.05};
    q.cameras.push_back(camera);
    if (method.multi) {
      // Cameras within ~0.3 m of the rig origin, looking outwards.
      const double yaw = 2 * std::numbers::pi * c / num_cameras;
      const Eigen::Quaterniond cam_from_rig_r(
          Eigen::AngleAxisd(yaw + 0.2 * g(rng), Eigen::Vector3d::UnitY()));
      q.cam_from_rig.emplace_back(cam_from_rig_r,
                                  s * 0.3 * Eigen::Vector3d(g(rng), g(rng), g(rng)));
    }
  }
  const auto cam_from_rig = [&](int c) { return method.multi ? q.cam_from_rig[c] : Rigid3d(); };

  uint64_t next_id = 1;
  const auto add_map_point = [&](const Eigen::Vector3d& x) {
    const uint64_t id = next_id++;
    inst.point_map.points.emplace(id, x);
    inst.line_map.lines.emplace(id, PluckerLine::FromPointAndDirection(x, RandomUnit(rng)));
    return id;
  };
  // A random pixel of camera c and a point at a random depth along its ray,
  // in the query (rig) frame.
  const auto random_view = [&](int c, Eigen::Vector2d* xy, double* depth) {
    const Camera& camera = q.cameras[c];
    *xy = Eigen::Vector2d(u(rng) * camera.width, u(rng) * camera.height);
    *depth = options.scene_depth * (0.2 + 0.8 * u(rng));
    const Eigen::Vector3d ray = camera.CamFromImg(*xy);
    const Eigen::Vector3d x_cam = *depth * s * ray / ray.z();
    return Eigen::Vector3d(cam_from_rig(c).Inverse() * x_cam);
  };

  const int n = options.num_correspondences;
  const int inliers = std::max(1, static_cast<int>(std::lround(options.inlier_ratio * n)));
  for (int i = 0; i < n; ++i) {
    const int c = static_cast<int>(rng() % static_cast<uint64_t>(num_cameras));
    const bool inlier = i < inliers;
    Eigen::Vector2d xy;
    double depth;
    const Eigen::Vector3d x_local = random_view(c, &xy, &depth);
    QueryObservation o;
    o.camera = c;
    if (inlier) {
      o.id = add_map_point(world_from_query * x_local);
      o.xy = xy + options.noise_px * Eigen::Vector2d(g(rng), g(rng));
    } else {
      // A wrong match: the pixel (and its local point) sees something else
      // than the map point it is matched to.
      Eigen::Vector2d other_xy;
      double other_depth;
      const int other_camera = static_cast<int>(rng() % static_cast<uint64_t>(num_cameras));
      o.id = add_map_point(world_from_query * random_view(other_camera, &other_xy, &other_depth));
      o.xy = xy;
    }
    q.observations.push_back(o);
    if (method.local_points) {
      q.points_local.push_back(x_local + options.local_noise * depth * s *
                                             Eigen::Vector3d(g(rng), g(rng), g(rng)));
    }
    inst.is_inlier.push_back(inlier);
  }
  // Shuffle so that inliers are not a prefix.
  std::vector<size_t> order(n);
  for (int i = 0; i < n; ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), rng);
  Query shuffled = q;
  std::vector<char> inlier_flags(n);
  for (int i = 0; i < n; ++i) {
    shuffled.observations[i] = q.observations[order[i]];
    if (method.local_points) shuffled.points_local[i] = q.points_local[order[i]];
    inlier_flags[i] = inst.is_inlier[order[i]];
  }
  inst.query = std::move(shuffled);
  inst.is_inlier = std::move(inlier_flags);
  if (options.match_scores) {
    for (int i = 0; i < n; ++i) {
      inst.query.observations[i].match_ratio = DrawMatchRatio(inst.is_inlier[i] != 0, rng);
    }
  }
  inst.scene_size = options.scene_depth;
  return inst;
}

LocalizationError CompareLocalization(const Sim3d& estimate, const Sim3d& truth) {
  LocalizationError e;
  e.rotation_rad = estimate.rotation.angularDistance(truth.rotation);
  e.position = (estimate.Inverse().translation - truth.Inverse().translation).norm();
  return e;
}

}  // namespace linecloud
