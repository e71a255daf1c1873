#include "linecloud/synthetic/scene.h"

#include <cmath>
#include <numbers>
#include <random>

#include "linecloud/util/error.h"

namespace linecloud {
namespace {

struct Surface {
  Eigen::Vector3d origin, du, dv;  // spans origin + a du + b dv, a, b in [0,1]
  Eigen::Vector3d normal;          // facing into the room
  std::array<uint8_t, 3> color;
  double Area() const { return du.cross(dv).norm(); }
};

// The six faces of an axis-aligned box, normals pointing outwards (furniture)
// or inwards (the room).
void AddBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, bool inward,
            std::array<uint8_t, 3> color, std::vector<Surface>* surfaces) {
  const Eigen::Vector3d size = hi - lo;
  for (int axis = 0; axis < 3; ++axis) {
    const int a = (axis + 1) % 3, b = (axis + 2) % 3;
    for (int side = 0; side < 2; ++side) {
      Surface s;
      s.origin = lo;
      s.origin[axis] = side ? hi[axis] : lo[axis];
      s.du = Eigen::Vector3d::Zero();
      s.dv = Eigen::Vector3d::Zero();
      s.du[a] = size[a];
      s.dv[b] = size[b];
      s.normal = Eigen::Vector3d::Zero();
      s.normal[axis] = (side ? 1.0 : -1.0) * (inward ? -1.0 : 1.0);
      s.color = color;
      surfaces->push_back(s);
    }
  }
}

Rigid3d LookAt(const Eigen::Vector3d& center, double yaw, double pitch, double roll) {
  const Eigen::Vector3d up = Eigen::Vector3d::UnitY();
  const Eigen::Vector3d forward(std::cos(pitch) * std::sin(yaw), std::sin(pitch),
                                std::cos(pitch) * std::cos(yaw));
  const Eigen::Vector3d right = forward.cross(up).normalized();
  const Eigen::Vector3d down = forward.cross(right);
  Eigen::Matrix3d world_from_cam;
  world_from_cam << right, down, forward;
  const Eigen::Matrix3d cam_from_world =
      Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
      world_from_cam.transpose();
  Rigid3d pose;
  pose.rotation = Eigen::Quaterniond(cam_from_world).normalized();
  pose.translation = -(pose.rotation * center);
  return pose;
}

}  // namespace

void SyntheticSceneOptions::Check() const {
  if (num_points < 10) Fail("synthetic scene: num_points must be >= 10");
  if (num_map_images < 2) Fail("synthetic scene: num_map_images must be >= 2");
  if (num_queries < 0) Fail("synthetic scene: num_queries must be >= 0");
  if (!(noise_px >= 0) || !std::isfinite(noise_px)) {
    Fail("synthetic scene: noise_px must be finite and >= 0");
  }
  if (width < 16 || height < 16 || !(focal > 0)) {
    Fail("synthetic scene: invalid camera");
  }
}

SyntheticScene GenerateSyntheticScene(const SyntheticSceneOptions& options) {
  options.Check();
  std::mt19937_64 rng(options.seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::normal_distribution<double> gaussian(0.0, 1.0);

  const Eigen::Vector3d room = options.room_size;
  std::vector<Surface> surfaces;
  AddBox(Eigen::Vector3d::Zero(), room, /*inward=*/true, {180, 170, 150}, &surfaces);
  // Furniture: a table, a cupboard against a wall, a sofa.
  AddBox({3.5, 0.0, 2.5}, {5.5, 0.75, 3.5}, false, {120, 80, 40}, &surfaces);
  AddBox({0.0, 0.0, 5.5}, {1.2, 2.0, 7.0}, false, {90, 90, 110}, &surfaces);
  AddBox({7.0, 0.0, 0.0}, {9.5, 0.9, 1.0}, false, {60, 110, 70}, &surfaces);
  std::vector<double> cumulative;
  double total = 0;
  for (const Surface& s : surfaces) cumulative.push_back(total += s.Area());

  Camera camera;
  camera.camera_id = 1;
  camera.model_id = CameraModelId::kSimpleRadial;
  camera.width = options.width;
  camera.height = options.height;
  camera.params = {options.focal, options.width / 2.0, options.height / 2.0, options.radial_k};

  // Points on surfaces, area-weighted; colour = surface colour + texture.
  struct ScenePoint {
    Eigen::Vector3d xyz, normal;
    std::array<uint8_t, 3> color;
  };
  std::vector<ScenePoint> points;
  while (static_cast<int>(points.size()) < options.num_points) {
    const double pick = uniform(rng) * total;
    const size_t k =
        std::lower_bound(cumulative.begin(), cumulative.end(), pick) - cumulative.begin();
    const Surface& s = surfaces[std::min(k, surfaces.size() - 1)];
    ScenePoint p;
    p.xyz = s.origin + uniform(rng) * s.du + uniform(rng) * s.dv;
    // Furniture inside other furniture or outside the room is invisible.
    if ((p.xyz.array() < -1e-9).any() || (p.xyz.array() > room.array() + 1e-9).any()) {
      continue;
    }
    p.normal = s.normal;
    const int shade = static_cast<int>(60 * uniform(rng)) - 30;
    for (int c = 0; c < 3; ++c) {
      p.color[c] = static_cast<uint8_t>(std::clamp(s.color[c] + shade, 0, 255));
    }
    points.push_back(p);
  }

  // Cameras inside the room at standing height, looking around.
  const auto random_pose = [&]() {
    const Eigen::Vector3d center(room.x() * (0.2 + 0.6 * uniform(rng)), 1.2 + 0.6 * uniform(rng),
                                 room.z() * (0.2 + 0.6 * uniform(rng)));
    const double yaw = 2.0 * std::numbers::pi * uniform(rng);
    const double pitch = (uniform(rng) - 0.5) * 0.5;  // ±14°
    const double roll = (uniform(rng) - 0.5) * 0.2;   // ±6°
    return LookAt(center, yaw, pitch, roll);
  };
  const auto observe = [&](const Rigid3d& cam_from_world, size_t i, Eigen::Vector2d* xy) {
    const ScenePoint& p = points[i];
    const Eigen::Vector3d center = cam_from_world.Center();
    if (p.normal.dot(center - p.xyz) <= 0) return false;  // back-facing
    const Eigen::Vector3d x = cam_from_world * p.xyz;
    if (x.z() < 0.2 || x.norm() > 12.0) return false;
    // Stay within the distortion model's monotonic range.
    if (x.hnormalized().norm() > 1.0) return false;
    const Eigen::Vector2d ideal = camera.ImgFromCam(x);
    *xy = ideal + options.noise_px * Eigen::Vector2d(gaussian(rng), gaussian(rng));
    return xy->x() >= 0 && xy->y() >= 0 && xy->x() < options.width && xy->y() < options.height;
  };

  SyntheticScene scene;
  scene.extent = room.norm();
  Reconstruction& model = scene.model;
  model.cameras[camera.camera_id] = camera;
  std::vector<std::vector<TrackElement>> tracks(points.size());
  for (int m = 0; m < options.num_map_images; ++m) {
    Image image;
    image.image_id = static_cast<uint32_t>(m + 1);
    image.camera_id = camera.camera_id;
    image.name = fmt::format("map_{:03d}.png", m);
    image.cam_from_world = random_pose();
    for (size_t i = 0; i < points.size(); ++i) {
      Point2D p2;
      if (!observe(image.cam_from_world, i, &p2.xy)) continue;
      p2.point3D_id = i + 1;
      tracks[i].push_back({image.image_id, static_cast<uint32_t>(image.points2D.size())});
      image.points2D.push_back(p2);
    }
    model.images[image.image_id] = std::move(image);
  }
  // Keep points seen by >= 2 map images; unlink the others from their images.
  for (size_t i = 0; i < points.size(); ++i) {
    if (tracks[i].size() >= 2) {
      Point3D p;
      p.xyz = points[i].xyz;
      p.color = points[i].color;
      p.error = options.noise_px;
      p.track = tracks[i];
      model.points3D[i + 1] = std::move(p);
    } else {
      for (const TrackElement& el : tracks[i]) {
        model.images[el.image_id].points2D[el.point2D_idx].point3D_id = kInvalidPoint3DId;
      }
    }
  }

  for (int q = 0; q < options.num_queries; ++q) {
    SyntheticQuery query;
    query.name = fmt::format("query_{:03d}", q);
    query.camera = camera;
    query.cam_from_world = random_pose();
    query.gravity_in_cam = query.cam_from_world.rotation * scene.gravity_in_world;
    for (size_t i = 0; i < points.size(); ++i) {
      SyntheticObservation obs;
      if (!model.points3D.count(i + 1)) continue;
      if (!observe(query.cam_from_world, i, &obs.xy)) continue;
      obs.point3D_id = i + 1;
      query.observations.push_back(obs);
    }
    scene.queries.push_back(std::move(query));
  }
  return scene;
}

}  // namespace linecloud
