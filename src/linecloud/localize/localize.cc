#include "linecloud/localize/localize.h"

#include "linecloud/io/colmap_model.h"
#include "linecloud/io/ply.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <map>
#include <memory>
#include <optional>
#include <cmath>
#include <numbers>
#include <numeric>
#include <span>

#include <Eigen/Geometry>

#include "linecloud/estimation/pose_data.h"
#include "linecloud/estimation/pose_estimator.h"
#include "linecloud/lifting/lifting.h"
#include "linecloud/util/clock.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using Clock = std::chrono::steady_clock;

void CheckQuery(const MethodInfo& method, const Query& q, std::string_view source) {
  if (q.cameras.empty()) Fail("{}: 'cameras' is empty", source);
  for (size_t c = 0; c < q.cameras.size(); ++c) {
    q.cameras[c].Check(fmt::format("{}: cameras[{}]", source, c));
  }
  if (!q.cam_from_rig.empty() && q.cam_from_rig.size() != q.cameras.size()) {
    Fail("{}: 'cam_from_rig' has {} poses for {} cameras", source, q.cam_from_rig.size(),
         q.cameras.size());
  }
  for (size_t c = 0; c < q.cam_from_rig.size(); ++c) {
    if (!q.cam_from_rig[c].rotation.coeffs().allFinite() ||
        !q.cam_from_rig[c].translation.allFinite()) {
      Fail("{}: cam_from_rig[{}] is not finite", source, c);
    }
  }
  if (!method.multi && q.cameras.size() != 1) {
    Fail(
        "{}: method {} localizes one image, but the query has {} cameras (use the m- "
        "method)",
        source, method.name, q.cameras.size());
  }
  if (q.observations.size() < static_cast<size_t>(method.sample_size)) {
    Fail("{}: method {} needs at least {} observations, got {}", source, method.name,
         method.sample_size, q.observations.size());
  }
  for (size_t i = 0; i < q.observations.size(); ++i) {
    const QueryObservation& o = q.observations[i];
    if (o.camera < 0 || static_cast<size_t>(o.camera) >= q.cameras.size()) {
      Fail("{}: observations[{}].camera = {} but there are {} cameras", source, i, o.camera,
           q.cameras.size());
    }
    if (!o.xy.allFinite()) Fail("{}: observations[{}].xy is not finite", source, i);
    if (o.match_ratio && !(std::isfinite(*o.match_ratio) && *o.match_ratio >= 0)) {
      Fail("{}: observations[{}].ratio = {} is not a match ratio (finite, >= 0)", source, i,
           *o.match_ratio);
    }
  }
  if (method.local_points) {
    if (q.points_local.size() != q.observations.size()) {
      Fail("{}: method {} needs 'points_local' with one point per observation ({}), got {}", source,
           method.name, q.observations.size(), q.points_local.size());
    }
    for (size_t i = 0; i < q.points_local.size(); ++i) {
      if (!q.points_local[i].allFinite()) {
        Fail("{}: points_local[{}] is not finite", source, i);
      }
    }
  }
  if (method.gravity) {
    for (const auto& [g, name] :
         {std::pair{&q.gravity_query, "gravity_query"}, std::pair{&q.gravity_map, "gravity_map"}}) {
      if (!g->has_value()) Fail("{}: method {} needs '{}'", source, method.name, name);
      if (!(*g)->allFinite() || !((*g)->norm() > 0)) {
        Fail("{}: '{}' must be a finite non-zero vector", source, name);
      }
    }
  }
}

}  // namespace

PointMap PointMapFromModel(const Reconstruction& model) {
  PointMap map;
  map.points.reserve(model.points3D.size());
  for (const auto& [id, point] : model.points3D) map.points.emplace(id, point.xyz);
  return map;
}

LineMap LineMapFromCloud(const LineCloud& cloud) {
  LineMap map;
  map.lines.reserve(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) map.lines.emplace(cloud.ids[i], cloud.lines[i]);
  return map;
}

LineMap LineMapByPointId(const LineCloud& cloud, const LiftingKey& key) {
  if (cloud.key_fingerprint != key.Fingerprint()) {
    Fail("line cloud was lifted with another key (fingerprint {}, key {})",
         ToHex(cloud.key_fingerprint), ToHex(key.Fingerprint()));
  }
  const std::vector<uint64_t> point_ids =
      cloud.keyed_line_ids ? PointIdsOfLines(key, cloud.ids) : cloud.ids;
  LineMap map;
  map.lines.reserve(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) map.lines.emplace(point_ids[i], cloud.lines[i]);
  return map;
}

void SuccessCriteria::Check() const {
  if (min_inliers_points < 0 || min_inliers_lines < 0) {
    Fail("minimum inlier counts must be non-negative, got {} / {}", min_inliers_points,
         min_inliers_lines);
  }
  if (!(min_inlier_ratio >= 0 && min_inlier_ratio <= 1)) {
    Fail("minimum inlier ratio must be in [0, 1], got {}", min_inlier_ratio);
  }
  if (!(max_focal_discrepancy >= 0) || !std::isfinite(max_focal_discrepancy)) {
    Fail("maximum focal-length discrepancy must be a non-negative fraction, got {}",
         max_focal_discrepancy);
  }
  if (!(max_rotation_uncertainty_deg > 0)) {
    Fail("maximum rotation uncertainty must be positive, got {}", max_rotation_uncertainty_deg);
  }
  if (!(max_position_uncertainty >= 0) || !std::isfinite(max_position_uncertainty)) {
    Fail("maximum position uncertainty must be a non-negative fraction, got {}",
         max_position_uncertainty);
  }
  if (!(max_principal_discrepancy >= 0) || !std::isfinite(max_principal_discrepancy)) {
    Fail("maximum principal-point discrepancy must be a non-negative fraction, got {}",
         max_principal_discrepancy);
  }
  if (!(max_runner_up_share >= 0 && max_runner_up_share <= 1)) {
    Fail("maximum runner-up share must be in [0, 1], got {}", max_runner_up_share);
  }
}

void LocalizeOptions::Check() const {
  success.Check();
  ransac.Check();
  refinement.Check();
  local_refinement.Check();
}

std::vector<PlyCamera> LocalizedCameras(const Query& query, const LocalizeResult& result) {
  std::vector<PlyCamera> cameras;
  const Sim3d world_from_query = result.query_from_world.Inverse();
  for (size_t c = 0; c < query.cameras.size(); ++c) {
    const Rigid3d cam_from_rig = c < query.cam_from_rig.size() ? query.cam_from_rig[c] : Rigid3d();
    const Sim3d rig_from_cam =
        Sim3d(1.0, cam_from_rig.rotation, cam_from_rig.translation).Inverse();
    cameras.push_back({world_from_query * rig_from_cam, query.cameras[c]});
  }
  return cameras;
}

Eigen::Matrix3d GravityAlignment(const Eigen::Vector3d& gravity) {
  return Eigen::Quaterniond::FromTwoVectors(gravity.normalized(), -Eigen::Vector3d::UnitY())
      .toRotationMatrix();
}

std::vector<int> MatchRanking(const std::vector<QueryObservation>& observations) {
  std::vector<int> ranking;
  for (const QueryObservation& o : observations) {
    if (!o.match_ratio) return {};
  }
  ranking.resize(observations.size());
  std::iota(ranking.begin(), ranking.end(), 0);
  std::stable_sort(ranking.begin(), ranking.end(), [&](int a, int b) {
    return *observations[static_cast<size_t>(a)].match_ratio <
           *observations[static_cast<size_t>(b)].match_ratio;
  });
  return ranking;
}

void CheckMethodAndMap(const MethodInfo& method, const LocalizationMap& map) {
  if (!method.implemented) Fail("method {} has no minimal solver in this build yet", method.name);
  const bool line_map = std::holds_alternative<LineMap>(map);
  if (method.lines != line_map) {
    Fail("method {} needs a {} map, but got a {}", method.name,
         method.lines ? "line cloud" : "point model", line_map ? "line cloud" : "point model");
  }
}

namespace {

// PrepareQuery for a query CheckQuery has passed (Localize checks once, then
// prepares the undistortable subset). Errors name observation
// original_index[i] when given (the index in the query as the user wrote it).
PreparedQuery PrepareCheckedQuery(const MethodInfo& method, const Query& query,
                                  const LocalizationMap& map, std::string_view source,
                                  std::span<const int> original_index = {}) {
  const bool line_map = std::holds_alternative<LineMap>(map);
  const auto index = [&](size_t i) {
    return original_index.empty() ? i : static_cast<size_t>(original_index[i]);
  };
  // +u: rotate both frames so that gravity is −y; the solvers then look for
  // a rotation about y. aligned = A x; undone on the result.
  PreparedQuery prepared;
  Eigen::Matrix3d align_query = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d align_map = Eigen::Matrix3d::Identity();
  if (method.gravity) {
    align_query = GravityAlignment(*query.gravity_query);
    align_map = GravityAlignment(*query.gravity_map);
  }
  prepared.aligned_from_query = Eigen::Quaterniond(align_query);
  prepared.aligned_from_map = Eigen::Quaterniond(align_map);
  const Eigen::Quaterniond& align_query_q = prepared.aligned_from_query;
  PoseData& data = prepared.data;
  for (size_t c = 0; c < query.cameras.size(); ++c) {
    Rigid3d cam_from_rig;
    if (method.multi && !query.cam_from_rig.empty()) cam_from_rig = query.cam_from_rig[c];
    // cam_from_aligned = cam_from_rig ∘ rig_from_aligned.
    data.cam_from_rig.push_back(cam_from_rig *
                                Rigid3d(align_query_q.inverse(), Eigen::Vector3d::Zero()));
  }
  for (size_t i = 0; i < query.observations.size(); ++i) {
    const QueryObservation& o = query.observations[i];
    const Camera& camera = query.cameras[o.camera];
    const Eigen::Vector3d ray = camera.CamFromImg(o.xy);
    if (!ray.allFinite() || !(ray.z() > 0)) {
      Fail("{}: observations[{}].xy = ({}, {}) cannot be undistorted by camera {}", source,
           index(i), o.xy.x(), o.xy.y(), o.camera);
    }
    data.camera.push_back(o.camera);
    data.normalized.push_back(ray.head<2>() / ray.z());
    data.focal.push_back(camera.MeanFocalLength());
    data.bearings.push_back(ray.normalized());
    if (method.local_points) data.points_local.push_back(align_query * query.points_local[i]);
    if (line_map) {
      const auto& lines = std::get<LineMap>(map).lines;
      const uint64_t id = o.line_id.value_or(o.id);
      const auto it = lines.find(id);
      if (it == lines.end()) {
        // [newcomer] The usual cause: a query made against another map, or
        // against this map's points lifted under another key.
        Fail(
            "{}: observations[{}].{} = {} is not in the map; a query made for another map, or "
            "for one lifted under another key (its line ids differ), looks like this: make the "
            "query from this map",
            source, index(i), o.line_id ? "line_id" : "id", id);
      }
      data.lines.push_back(PluckerLine(align_map * it->second.v, align_map * it->second.w));
    } else {
      const auto& points = std::get<PointMap>(map).points;
      const auto it = points.find(o.id);
      if (it == points.end())
        Fail("{}: observations[{}].id = {} is not in the map", source, index(i), o.id);
      data.points.push_back(align_map * it->second);
    }
  }
  data.ranking = MatchRanking(query.observations);
  return prepared;
}

}  // namespace

PreparedQuery PrepareQuery(const MethodInfo& method, const Query& query, const LocalizationMap& map,
                           std::string_view source) {
  CheckMethodAndMap(method, map);
  CheckQuery(method, query, source);
  return PrepareCheckedQuery(method, query, map, source);
}

Sim3d PreparedQuery::ToQueryFromWorld(const Sim3d& aligned_pose) const {
  return Sim3d(1.0, aligned_from_query.inverse(), Eigen::Vector3d::Zero()) * aligned_pose *
         Sim3d(1.0, aligned_from_map, Eigen::Vector3d::Zero());
}

// A common mistake the camera's numbers show, as advice, or "": a photo
// turned with only width and height swapped (a portrait photo, a landscape
// principal point, or the other way round), or a camera made for the photo
// at another size (its principal point a multiple of this one's centre).
// The factor the camera looks made for another size by: its principal point
// the centre of an image that many times this one's (the same in both axes,
// within 5 %, and more than 1.2 times off); 0 when it does not look so.
double SizeFactor(const std::array<double, 2>& size, const std::array<double, 2>& principal) {
  const double sx = principal[0] / (0.5 * size[0]), sy = principal[1] / (0.5 * size[1]);
  const bool proportional = std::abs(sx - sy) < 0.05 * std::max(sx, sy);
  return proportional && sx > 0 && std::abs(std::log(sx)) > std::log(1.2) ? sx : 0.0;
}

std::string CameraMistakeHint(const std::array<double, 2>& size,
                              const std::array<double, 2>& principal) {
  const auto& [w, h] = size;
  const auto& [cx, cy] = principal;
  if ((h > w && cx > 0.6 * w && cy < 0.4 * h) || (w > h && cx < 0.4 * w && cy > 0.6 * h)) {
    return fmt::format(
        "the photo looks turned with only the camera's width and height swapped: turn the "
        "camera too (fx and fy swapped; the principal point ({:.0f}, {:.0f}) for a clockwise "
        "turn, ({:.0f}, {:.0f}) for a counter-clockwise one)",
        w - cy, cx, cy, h - cx);
  }
  if (const double sx = SizeFactor(size, principal); sx > 0) {
    const double sy = cy / (0.5 * h);
    return fmt::format(
        "the camera looks made for the photo at about {:.2g} times this size (its principal point "
        "is the centre of a {:.0f}x{:.0f} image): scale fx, fy, cx and cy with the photo (by "
        "about {:.3g}); for a crop of a larger photo, its camera with cx and cy shifted by the "
        "crop's corner is right",
        sx, sx * w, sy * h, 1 / sx);
  }
  return "";
}

std::string CameraMistakeHint(const Camera& camera) {
  const Eigen::Vector2d pp = camera.PrincipalPoint();
  return CameraMistakeHint({static_cast<double>(camera.width), static_cast<double>(camera.height)},
                           {pp.x(), pp.y()});
}

namespace {

// A camera parameter's test (CalibrationCheck) as one verdict: outside its
// 99.7 % interval with a deviance to match, the interval narrow enough to
// judge, and the discrepancy beyond what the criteria allow.
struct ParameterVerdict {
  bool outside = false;  // outside the interval and narrow: the data say it is wrong
  bool refused = false;  // ... and by more than allowed
  double deviance = 0;
};

ParameterVerdict JudgeParameter(double shift, double se, double deviance, double allowed,
                                double narrow_width, bool at_edge) {
  ParameterVerdict v;
  v.outside =
      at_edge || (std::abs(shift) > kCalibrationZ * se &&
                  deviance > kCalibrationZ * kCalibrationZ && kCalibrationZ * se <= narrow_width);
  v.refused = v.outside && std::abs(shift) > allowed;
  v.deviance = deviance;
  return v;
}

// With the focal length refined: why the principal point fitted jointly with
// it contradicts the camera's (beyond the criteria's share of the size and 3
// standard errors), naming the axis farther off; "" when it does not.
std::string RefitPrincipalFailure(const CalibrationCheck& check, const SuccessCriteria& c) {
  if (!check.refit_principal || !(c.max_principal_discrepancy > 0)) return "";
  int worst = -1;
  double worst_share = 0;
  for (int axis = 0; axis < 2; ++axis) {
    const double size = check.image_size[axis];
    const double shift = (*check.refit_principal)[axis] - check.given_principal[axis];
    // The joint fit's own standard error where it is the larger (the
    // principal point trades off with the tangential terms fitted with it).
    const double joint_se = check.joint.se[static_cast<size_t>(1 + axis)];
    const double se = std::isfinite(joint_se) ? std::max(check.principal_se[axis], joint_se)
                                              : check.principal_se[axis];
    if (std::abs(shift) > c.max_principal_discrepancy * size &&
        (!std::isfinite(se) || std::abs(shift) > kCalibrationZ * se) &&
        std::abs(shift) / size > worst_share) {
      worst = axis, worst_share = std::abs(shift) / size;
    }
  }
  if (worst < 0) return "";
  return fmt::format(
      "with its focal length refined, the camera's principal point looks wrong: fitted with the "
      "focal length, the inliers put {} at {:.0f} px, the camera says {:.0f} px ({:.0f} % of the "
      "{} off); refining the focal length does not mend a wrong principal point: send the camera "
      "of the photo as it is",
      worst == 0 ? "cx" : "cy", (*check.refit_principal)[worst], check.given_principal[worst],
      100 * worst_share, worst == 0 ? "width" : "height");
}

// Where the joint fit may start besides the camera as given (θ = 0): at the
// profiles' fits, each with the others as given, for a camera whose focal
// length is `focal` (the given one's, or the refined one) where the camera
// as given has `given_focal`.
std::vector<std::array<double, 3>> ProfileStarts(const CalibrationCheck& check, double focal,
                                                 double given_focal) {
  const double base = std::log(focal / given_focal);
  return {{std::log(check.best_fit_focal / given_focal), 0, 0},
          {base, check.best_fit_principal[0] - check.given_principal[0], 0},
          {base, 0, check.best_fit_principal[1] - check.given_principal[1]}};
}

// Which calibration parameter the inliers blame, the others free (the joint
// fit, FitCalibrationJointly): the one that moved farthest in its standard errors (each
// profile's; the joint fit's when a profile is flat). One at a time, a
// principal point 5 % off in x looks like a focal length 9 % off nearly as
// well (the demo room: deviance 284 for the focal length, 262 for cx) or
// like a shift in y; jointly, the others stay near their given values.
// Among the parameters the joint fit itself refuses, when there are any;
// -1 when it moves none significantly (the profiles then name it).
int BlamedParameter(const CalibrationCheck& check,
                    const std::array<bool, kJointParameters>& joint_refused) {
  const bool any = joint_refused[0] || joint_refused[1] || joint_refused[2];
  const std::array<double, 3> se = {check.log_focal_se, check.principal_se[0],
                                    check.principal_se[1]};
  int blamed = -1;
  double largest = -1;
  for (int k = 0; k < 3; ++k) {
    if (any && !joint_refused[static_cast<size_t>(k)]) continue;
    // Only a parameter the joint fit moves significantly (an EuRoC crop's
    // true camera, refused by one profile, was named "focal length +0 %").
    const double joint_se = check.joint.se[static_cast<size_t>(k)];
    if (std::isfinite(joint_se) &&
        std::abs(check.joint.theta[static_cast<size_t>(k)]) <= kCalibrationZ * joint_se) {
      continue;
    }
    double s_k = se[static_cast<size_t>(k)];
    if (!(std::isfinite(s_k) && s_k > 0)) s_k = check.joint.se[static_cast<size_t>(k)];
    const double z = std::abs(check.joint.theta[static_cast<size_t>(k)]) /
                     (std::isfinite(s_k) && s_k > 0 ? s_k : 1.0);
    if (z > largest) largest = z, blamed = k;
  }
  return blamed;
}

}  // namespace

std::string CalibrationFailure(const CalibrationCheck& check, double given_focal,
                               const SuccessCriteria& c) {
  // The focal length in log k, each axis of the principal point in pixels
  // (judged once its interval is within 5 % of the size: on a flat wall the
  // principal point and the rotation trade off).
  std::array<ParameterVerdict, 3> v;
  if (c.max_focal_discrepancy > 0) {
    v[0] = JudgeParameter(std::log(check.best_fit_focal / given_focal), check.log_focal_se,
                          check.deviance, /*allowed=*/0, c.max_focal_discrepancy, check.at_edge[0]);
    v[0].refused = v[0].refused &&
                   std::abs(check.best_fit_focal / given_focal - 1.0) > c.max_focal_discrepancy;
  }
  if (c.max_principal_discrepancy > 0) {
    for (int axis = 0; axis < 2; ++axis) {
      const double size = check.image_size[axis];
      v[1 + axis] = JudgeParameter(check.best_fit_principal[axis] - check.given_principal[axis],
                                   check.principal_se[axis], check.principal_deviance[axis],
                                   c.max_principal_discrepancy * size,
                                   std::max(0.05, c.max_principal_discrepancy) * size,
                                   check.at_edge[static_cast<size_t>(1 + axis)]);
    }
  }
  // The camera as a whole: each parameter of the joint fit judged as the
  // profiles' are, with its marginal standard error, once the given camera's
  // deviance rejects it; with the focal length refined, every parameter but
  // it (fy 1 % off with cy 2 % off: the refined focal length took +6.8 % and
  // the profiles at it found cy where it was given — a 1.3° / 0.6 m
  // "success" for an outsider).
  // The aspect ratio and the distortion: the change beyond what matters 1 %
  // in fy / fx, 0.02 in λ (0.8 % of a 35 mm film's corner radius).
  std::array<bool, kJointParameters> joint_refused = {};
  std::array<double, kJointParameters> beyond = {};  // how many times its limit it is off
  const JointCalibration& j = check.joint;
  // Per parameter: the change beyond what matters and the widest 99.7 %
  // interval judged (for the principal point, fractions of the size).
  const bool checked = c.max_principal_discrepancy > 0;
  const std::array<double, kJointParameters> limits = {
      c.max_focal_discrepancy, c.max_principal_discrepancy, c.max_principal_discrepancy,
      checked ? 0.01 : 0.0,    checked ? 0.02 : 0.0,        checked ? 0.004 : 0.0,
      checked ? 0.004 : 0.0};
  const std::array<double, kJointParameters> narrow = {
      limits[0], std::max(0.05, limits[1]), std::max(0.05, limits[2]), 0.03, 0.1, 0.01, 0.01};
  if (j.RejectsGiven()) {
    for (int k = 0; k < kJointParameters; ++k) {
      const size_t i = static_cast<size_t>(k);
      if (!j.active[i] || (k == 0 && check.refit_principal)) continue;
      const double size = k == 1 || k == 2 ? check.image_size[i - 1] : 1.0;
      const double off =
          k == 0 || k == 3 ? std::abs(std::exp(j.theta[i]) - 1) : std::abs(j.theta[i]);
      // Outside its interval with the standard error widened to the deviance
      // (se_scale: a true camera's p1 was "beyond 3 σ" of a fit no better
      // than the given camera's beyond chance).
      const double se = j.se[i] * j.se_scale;
      joint_refused[i] = limits[i] > 0 && std::isfinite(se) &&
                         std::abs(j.theta[i]) > kCalibrationZ * se &&
                         kCalibrationZ * se <= narrow[i] * size && off > limits[i] * size;
      beyond[i] = joint_refused[i] ? off / (limits[i] * size) : 0.0;
    }
  }
  const int farthest =
      static_cast<int>(std::max_element(beyond.begin(), beyond.end()) - beyond.begin());
  const int joint_first = beyond[static_cast<size_t>(farthest)] > 0 ? farthest : -1;
  // Without the joint fit's verdict: the aspect ratio's and the distortion's
  // own profiles, judged as the others and named first when they explain
  // more (an fy 5 % off also moves the focal length and cx that fit best).
  double largest = 0;
  for (const ParameterVerdict& p : v) largest = std::max(largest, p.outside ? p.deviance : 0.0);
  const auto rejected = [&](const CalibrationCheck::Extra& e, double allowed, double narrow) {
    return joint_first < 0 && e.tested &&
           JudgeParameter(e.best, e.se, e.deviance, allowed, narrow, e.at_edge).refused &&
           e.deviance >= largest;
  };
  const CalibrationCheck::Extra& a = check.log_aspect;
  if (joint_first == 3 || rejected(a, 0.01, 0.03)) {
    const double best = joint_first == 3 ? j.theta[3] : a.best;
    return fmt::format(
        "the camera's aspect ratio looks wrong: the inliers fit fy / fx {:.3f} times the "
        "camera's ({:+.1f} %); send the photo's own fx and fy (a photo stretched or resized in "
        "one direction only looks like this)",
        std::exp(best), 100 * (std::exp(best) - 1));
  }
  const CalibrationCheck::Extra& k = check.radial;
  if (joint_first == 4 || rejected(k, 0.02, 0.1)) {
    return fmt::format(
        "the camera's distortion looks wrong: the inliers fit a radial distortion of about k1 "
        "{:+.3f} (division model) beyond the camera's{}; a photo sent without its distortion "
        "parameters (or with another camera's) looks like this: send the camera's model with "
        "its distortion (e.g. OPENCV fx fy cx cy k1 k2 p1 p2)",
        joint_first == 4 ? j.theta[4] : k.best,
        k.at_edge ? " or beyond (the end of the range searched)" : "");
  }
  if (joint_first == 5 || joint_first == 6) {
    return fmt::format(
        "the camera's tangential distortion looks wrong: the inliers fit p1, p2 {:+.4f}, {:+.4f} "
        "from the camera's; a calibration whose tangential terms traded off with its principal "
        "point, or another camera's distortion, looks like this: send the photo's own calibration",
        j.theta[5], j.theta[6]);
  }
  if (std::string wrong = RefitPrincipalFailure(check, c); !wrong.empty()) return wrong;
  const bool joint_refuses = joint_refused[0] || joint_refused[1] || joint_refused[2];
  if (!v[0].refused && !v[1].refused && !v[2].refused && !joint_refuses) return "";
  // Refused: named after the parameter whose refit explains the inliers best
  // (the largest deviance among those the data reject). A focal length 10 %
  // off also moves the principal point that fits best; its own deviance is
  // then the larger one (fountain, Herz-Jesu, entry: 58 of 58).
  // The joint fit (BlamedParameter) decides when it was made: its estimate
  // is then the one named, with the profile's standard error.
  // A parameter off beyond the range searched is the grossest error: named
  // first (a corner crop sent with a centred principal point, 49 % of the
  // width off, was blamed on the focal length by the joint fit).
  int edge = -1;
  for (int k = 0; k < 3; ++k) {
    if (check.at_edge[static_cast<size_t>(k)] && v[k].outside &&
        (edge < 0 || v[k].deviance > v[edge].deviance)) {
      edge = k;
    }
  }
  const int blamed = j.fitted ? BlamedParameter(check, joint_refused) : -1;
  int culprit = edge >= 0 ? edge : blamed;
  const bool joint = edge < 0 && blamed >= 0;
  if (culprit < 0) {
    for (int k = 0; k < 3; ++k) {
      if (v[k].outside && (culprit < 0 || v[k].deviance > v[culprit].deviance)) culprit = k;
    }
  }
  if (culprit < 0) culprit = v[0].refused ? 0 : (v[1].refused ? 1 : 2);
  std::string hint = CameraMistakeHint(check.image_size, check.given_principal);
  if (culprit == 0) {
    const double best = joint ? given_focal * std::exp(j.theta[0]) : check.best_fit_focal;
    const double se = std::isfinite(check.log_focal_se) ? check.log_focal_se : 0.0;
    const double off = best / given_focal - 1.0;
    const std::string fit =
        check.at_edge[0] && !joint
            ? fmt::format("{:.1f} px or beyond (the end of the range searched)", best)
            : fmt::format("{:.1f} px (99.7 % interval {:.1f}-{:.1f} px)", best,
                          best * std::exp(-kCalibrationZ * se),
                          best * std::exp(kCalibrationZ * se));
    return fmt::format(
        "the camera's focal length looks wrong: the inliers fit {}, the camera says {:.1f} px "
        "({:+.0f} %); {}",
        fit, given_focal, 100 * off,
        // No advice to refine the focal length: with the principal point a
        // few per cent off too, the refit settles in a compensating fit (an
        // outsider: focal x0.97 with cx +2 % gave 1.3° "successes" with it).
        hint.empty() ? std::string("send the focal length the photo was taken with (scaled "
                                   "with the photo, if it was resized) with its principal point")
                     : hint);
  }
  const int axis = culprit - 1;
  const double size = check.image_size[axis];
  const double se = std::isfinite(check.principal_se[axis]) ? check.principal_se[axis] : 0.0;
  const double best = joint ? check.given_principal[axis] + j.theta[static_cast<size_t>(culprit)]
                            : check.best_fit_principal[axis];
  const std::string fit =
      check.at_edge[static_cast<size_t>(culprit)]
          ? fmt::format("{:.0f} px or beyond (the end of the range searched)", best)
          : fmt::format("{:.0f} px (99.7 % interval {:.0f}-{:.0f})", best,
                        best - kCalibrationZ * se, best + kCalibrationZ * se);
  return fmt::format(
      "the camera's principal point looks wrong: the inliers fit {} = {}, the camera says {:.0f} "
      "px ({:.0f} % of the {} off); {}",
      axis == 0 ? "cx" : "cy", fit, check.given_principal[axis],
      100 * std::abs(best - check.given_principal[axis]) / size, axis == 0 ? "width" : "height",
      hint.empty() ? "a photo cropped or resized after its calibration, or the principal point of "
                     "another sensor mode, looks like this: send the camera of the photo as it is"
                   : hint);
}

std::string SuccessFailure(const MethodInfo& method, const LocalizeResult& r,
                           const SuccessCriteria& c) {
  const int min_inliers = method.lines ? c.min_inliers_lines : c.min_inliers_points;
  const int inliers = static_cast<int>(r.inliers.size());
  const double ratio =
      r.num_correspondences > 0 ? static_cast<double>(inliers) / r.num_correspondences : 0.0;
  if (inliers < min_inliers) {
    return fmt::format(
        "too few inliers: {} matches fit the best pose, fewer than the {} a {} map needs (option "
        "min_inliers); a photo of another place, or a wrong camera, looks like this",
        inliers, min_inliers, method.lines ? "line" : "point");
  }
  if (ratio < c.min_inlier_ratio) {
    return fmt::format(
        "too few of the matches fit: {} of {} ({:.0f} %, fewer than the {:.0f} % needed: option "
        "min_inlier_ratio); a photo of another place, one the map sees from too far, or a wrong "
        "camera (a photo resized in one direction with its old camera), looks like this",
        inliers, r.num_correspondences, 100 * ratio, 100 * c.min_inlier_ratio);
  }
  if (c.max_runner_up_share > 0 && r.stats.runner_up_own_inliers > 0 &&
      r.stats.runner_up_own_inliers >= c.max_runner_up_share * r.stats.num_inliers &&
      r.runner_up_rotation_deg > 1.0) {
    return fmt::format(
        "ambiguous: two poses {:.1f}° apart fit different matches almost equally well ({} and "
        "{}); a repeated structure — another photo, or one with more of the scene, tells them "
        "apart",
        r.runner_up_rotation_deg, r.stats.num_inliers, r.stats.runner_up_own_inliers);
  }
  if (r.calibration_check) {
    if (std::string wrong = CalibrationFailure(*r.calibration_check, r.given_focal, c);
        !wrong.empty()) {
      return wrong;
    }
  }
  // A rig whose cam_from_rig is wrong for one camera (a device's tracking, a
  // two-view reconstruction of a facade: entry-P10's 14.7° off) still gets a
  // pose from its other cameras' matches; that pose is no rig pose. Each
  // camera with the matches to judge must fit it as the whole query must.
  for (size_t cam = 0; cam < r.camera_observations.size(); ++cam) {
    const int m = r.camera_observations[cam];
    if (m < min_inliers || m == 0) continue;
    const double cam_ratio = static_cast<double>(r.camera_inliers[cam]) / m;
    if (cam_ratio < c.min_inlier_ratio) {
      return fmt::format(
          "camera {} does not fit the rig pose: {} of its {} matches are inliers ({:.3f}, below "
          "{:.2f}); check its cam_from_rig",
          cam, r.camera_inliers[cam], m, cam_ratio, c.min_inlier_ratio);
    }
  }
  if (!(r.uncertainty.rotation_deg <= c.max_rotation_uncertainty_deg)) {
    return fmt::format(
        "the rotation is undetermined: uncertainty {:.3g}° exceeds {:.3g}° "
        "(option max_rotation_uncertainty; weak geometry or a wrong calibration)",
        r.uncertainty.rotation_deg, c.max_rotation_uncertainty_deg);
  }
  if (c.max_position_uncertainty > 0 && r.inlier_distance > 0 && r.calibration_check &&
      !(r.uncertainty.position <= c.max_position_uncertainty * r.inlier_distance)) {
    return fmt::format(
        "the position is undetermined: uncertainty {:.3g} (1 σ, {:.3g} of it from the camera's "
        "calibration), {:.1f} % of the distance to the scene ({:.3g}), more than {:.1f} % "
        "(option max_position_uncertainty); a focal length or distortion a few per cent off "
        "looks like this: check the camera",
        r.uncertainty.position, r.calibration_check->position,
        100 * r.uncertainty.position / r.inlier_distance, r.inlier_distance,
        100 * c.max_position_uncertainty);
  }
  return "";
}

namespace {

// The median distance from camera 0 to what the inliers see: a point, or the
// point of a line nearest the viewing ray (closest points of two lines:
// s = ((p0 − c) × v)·(b × v) / |b × v|², p0 = v × w / |v|² the line's point
// nearest the origin).
double MedianInlierDistance(const PoseData& data, const std::vector<int>& inliers,
                            const Sim3d& query_from_world) {
  const Rigid3d& cam_from_rig = data.cam_from_rig.at(0);
  const Sim3d world_from_cam =
      (Sim3d(1.0, cam_from_rig.rotation, cam_from_rig.translation) * query_from_world).Inverse();
  const Eigen::Vector3d c = world_from_cam.translation;
  std::vector<double> distance;
  for (const int i : inliers) {
    const size_t k = static_cast<size_t>(i);
    if (data.camera[k] != 0) continue;
    if (!data.points.empty()) {
      distance.push_back((data.points[k] - c).norm());
      continue;
    }
    const Eigen::Vector3d b = world_from_cam.rotation * data.bearings[k];
    const Eigen::Vector3d& v = data.lines[k].v;
    const Eigen::Vector3d p0 = v.cross(data.lines[k].w) / v.squaredNorm();
    const Eigen::Vector3d n = b.cross(v);
    if (!(n.squaredNorm() > 1e-12 * v.squaredNorm())) continue;
    const double s = (p0 - c).cross(v).dot(n) / n.squaredNorm();
    if (s > 0 && std::isfinite(s)) distance.push_back(s * b.norm());
  }
  if (distance.empty()) return 0;
  std::nth_element(distance.begin(), distance.begin() + distance.size() / 2, distance.end());
  return distance[distance.size() / 2];
}

// The final LM on `inliers`; returns its iterations and adds its time.
int RefineStage(const MethodInfo& method, const PoseData& data, const std::vector<int>& inliers,
                const LocalizeOptions& options, Sim3d* pose, double* ms, double* final_cost) {
  if (!options.refine || inliers.size() < static_cast<size_t>(method.sample_size)) return 0;
  const auto start = Clock::now();
  RefineOptions refinement = options.refinement;
  // One camera's reprojections leave a similarity's scale free (a gauge that
  // slows the LM down): the camera's pose is refined as a rigid one, and the
  // scale comes from the local points (FitScaleToLocalPoints).
  refinement.similarity = method.similarity() && !SeenByOneCamera(data, inliers);
  const RefineSummary summary = RefinePose(data, inliers, refinement, pose);
  *ms += MsSince(start);
  if (final_cost) *final_cost = summary.final_cost;
  return summary.iterations;
}

// The joint fit's differencing step per camera parameter (log k, cx and cy
// shifts in px, log aspect, radial λ, p1, p2) for an image of this size: also
// the units in which refitted cameras are compared (FocalProfile::NearestFit).
std::array<double, kJointParameters> JointSteps(double width, double height) {
  return {0.01, 0.005 * width, 0.005 * height, 0.005, 0.01, 0.001, 0.001};
}

// The focal length's profile: for a factor k on the camera's focal length(s),
// the pose refined anew (the LM) on RANSAC's inliers, its final robust cost,
// and the sum of squared reprojection errors there (px², each at most the
// RANSAC threshold²). Pixel residuals use the focal being tried, so values
// compare like for like; the pose refined for each k is the focal length's
// information with the pose marginalised.
class FocalProfile {
 public:
  struct Point {
    double cost = 0;              // the LM's final cost (Cauchy)
    std::vector<double> squared;  // per inlier: r², px² (at most the RANSAC threshold²)
    // Per inlier its signed residual(s), px (two entries; the second 0 for a
    // line) and whether it has one (0: behind the camera, or no camera).
    std::vector<Eigen::Vector2d> residuals;
    std::vector<char> valid;
    Sim3d pose;  // the pose refined for this value
  };

  FocalProfile(const MethodInfo& method, const Query& query, const LocalizationMap& map,
               const std::vector<int>& inliers, const Sim3d& start_pose,
               const LocalizeOptions& options, double* refine_ms)
      : method_(method),
        query_(std::make_shared<const Query>(InliersOnly(query, inliers))),
        map_(map),
        inliers_(std::make_shared<const std::vector<int>>(Iota(inliers.size()))),
        start_(start_pose),
        options_(options),
        refine_ms_(refine_ms),
        radial_range_(RadialRange(*query_)),
        fits_(std::make_shared<std::map<Change, Point>>()) {}

  // Which camera parameter the profile moves: the focal length (by a factor
  // e^v), the principal point's x or y (by v pixels), fy alone (by e^v: the
  // aspect ratio) or the first radial distortion coefficient (by v).
  // p1, p2: tangential distortion (Brown–Conrady) the camera lacks, on its
  // undistorted image plane (the joint fit only).
  enum class Parameter { kLogFocal, kPrincipalX, kPrincipalY, kLogAspect, kRadial, kP1, kP2 };
  // A camera's change from the one given, by Parameter: (log k, cx and cy
  // shifts, log aspect, radial λ, p1, p2).
  using Change = std::array<double, 7>;

  Point At(double v) const {
    std::array<double, 3> theta = {0, 0, 0};
    if (parameter_ == Parameter::kLogAspect) return AtCamera(theta, v, 0);
    if (parameter_ == Parameter::kRadial) return AtCamera(theta, 0, v);
    theta[static_cast<size_t>(parameter_)] = v;
    return AtCamera(theta);
  }

  // (log k, shift of cx, shift of cy) at once, and the aspect ratio and
  // distortion changes. A camera the change makes implausible (a distortion
  // that folds the image) fits nothing: every residual at the threshold.
  // Each camera is refitted once (the camera as given is what every test
  // compares with; a profile's search and its curvature share values).
  Point AtCamera(const std::array<double, 3>& theta, double log_aspect = 0, double radial = 0,
                 const std::array<double, 2>& tangential = {0, 0}) const {
    const Change change = {
        base_[0] + theta[0], base_[1] + theta[1], base_[2] + theta[2], log_aspect, radial,
        tangential[0],       tangential[1]};
    if (const auto found = fits_->find(change); found != fits_->end()) return found->second;
    Point p = Refit(change, NearestFit(change));
    fits_->emplace(change, p);
    return p;
  }

  // The same profile about another camera: `base` (log k, cx and cy shifts)
  // added to every value tried.
  FocalProfile WithBase(const std::array<double, 3>& base) const {
    FocalProfile p = *this;
    p.base_ = base;
    return p;
  }
  // The same profile over another parameter.
  FocalProfile Over(Parameter parameter) const {
    FocalProfile p = *this;
    p.parameter_ = parameter;
    return p;
  }
  Parameter parameter() const { return parameter_; }
  double loss_scale() const { return options_.refinement.loss_scale; }
  // The range searched: the factor k in [1/1.5, 1.5] (log scale), or a
  // quarter of the image's width / height either way.
  std::array<double, 2> Range() const {
    const Camera& c = query_->cameras[0];
    switch (parameter_) {
      case Parameter::kLogFocal:
        return {std::log(1 / 1.5), std::log(1.5)};
      case Parameter::kPrincipalX:
        return {-0.25 * c.width, 0.25 * c.width};
      case Parameter::kPrincipalY:
        return {-0.25 * c.height, 0.25 * c.height};
      case Parameter::kLogAspect:
        return {std::log(1 / 1.2), std::log(1.2)};
      case Parameter::kP1:
      case Parameter::kP2:
        return {-0.05, 0.05};
      default:
        return radial_range_;
    }
  }

  // The value of least cost in Range(), to `tolerance` (of the value: log k,
  // or pixels), by golden sections over the whole range: 11 refits, starting
  // 10-40 % off, where a refit takes 10-30 LM iterations against 3-5 next to
  // a fitted value. Given a `step` (and the focal length not refined), the
  // camera as given first: when it costs no more than the values `step`
  // either side, the least cost lies between them and the given value is
  // returned (TestProfile's parabolas place the estimate there) — 2 refits,
  // the common case of a camera near its best fit. With the focal length
  // refined, the whole range always: a refined focal length absorbs a wrong
  // principal point, and the profile about it then has a basin at the given
  // value (cx 5 % off on the synthetic scene: p6L's profile stayed at +3 px,
  // 53 px from the truth, where the search over the range found -45 px).
  double Minimize(double tolerance, double step = 0, bool* bracketed = nullptr) const {
    const auto cost = [&](double v) { return At(v).cost; };
    const auto [lo, hi] = Range();
    if (step > 0 && !options_.refine_focal && lo < -step && step < hi) {
      const double given = cost(0);
      if (given <= cost(-step) && given <= cost(step)) {
        if (bracketed) *bracketed = true;
        return parameter_ == Parameter::kLogFocal ? 1.0 : 0.0;
      }
    }
    constexpr double kInvPhi = 0.6180339887498949;
    double a = lo, b = hi;
    double x1 = b - kInvPhi * (b - a), x2 = a + kInvPhi * (b - a);
    double f1 = cost(x1), f2 = cost(x2);
    while (b - a > tolerance) {
      if (f1 <= f2) {
        b = x2, x2 = x1, f2 = f1;
        x1 = b - kInvPhi * (b - a);
        f1 = cost(x1);
      } else {
        a = x1, x1 = x2, f1 = f2;
        x2 = a + kInvPhi * (b - a);
        f2 = cost(x2);
      }
    }
    const double v = 0.5 * (a + b);
    return parameter_ == Parameter::kLogFocal ? std::exp(v) : v;
  }

 private:
  // A radial distortion the camera lacks, in the division model on its
  // undistorted image plane: x ← x / (1 + λ |x|²) (Fitzgibbon, CVPR 2001;
  // λ ≈ k1 for small distortions). A polynomial k1 alone folds a wide-angle
  // image's corners (EuRoC beyond k1 -0.15, where its true distortion is k1
  // -0.28 balanced by k2 +0.07): the search stalled at the fold with no
  // deviance, and frames sent without their distortion kept a pose 1° off.
  // The division model does not fold while 1 + λ |x|² > 0.
  // Tangential distortion (p1, p2) the camera lacks is removed after it, to
  // first order: x -= (2 p1 x y + p2 (r² + 2 x²), p1 (r² + 2 y²) + 2 p2 x y)
  // (Brown, 1966), so that p is what the camera's p1, p2 miss, as λ is for
  // the radial term. A wrong p1 moves the principal point that fits: an
  // outsider set cy where the check said and got 1.2-4.8° "successes" with
  // p1 0.008-0.03. Both in one pass, the bearings made anew.
  static void ChangeDistortion(double lambda, const std::array<double, 2>& p, PoseData* data) {
    for (size_t k = 0; k < data->size(); ++k) {
      Eigen::Vector2d& x = data->normalized[k];
      x /= 1 + lambda * x.squaredNorm();
      const double xx = x.x() * x.x(), yy = x.y() * x.y(), xy = x.x() * x.y(), r2 = xx + yy;
      x -= Eigen::Vector2d(2 * p[0] * xy + p[1] * (r2 + 2 * xx),
                           p[0] * (r2 + 2 * yy) + 2 * p[1] * xy);
      data->bearings[k] = x.homogeneous().normalized();
    }
  }

  // The λ in [-0.4, 0.4] for which every inlier's 1 + λ |x|² stays above
  // 1/4 (its image plane stretched at most 4 times).
  static std::array<double, 2> RadialRange(const Query& query) {
    double largest = 0;
    for (const QueryObservation& o : query.observations) {
      const Eigen::Vector3d ray = query.cameras[0].CamFromImg(o.xy);
      if (ray.allFinite() && ray.z() > 0) {
        largest = std::max(largest, (ray.head<2>() / ray.z()).squaredNorm());
      }
    }
    return {largest > 0 ? std::max(-0.4, -0.75 / largest) : -0.4, 0.4};
  }

  // The query of the inliers alone: each value tried prepares (undistorts,
  // looks up) only what the refit uses, not every match (2 200 on a photo
  // of fountain for 300 inliers).
  static Query InliersOnly(const Query& query, const std::vector<int>& inliers) {
    Query subset = query;
    subset.observations.clear();
    subset.points_local.clear();
    for (const int i : inliers) {
      subset.observations.push_back(query.observations[static_cast<size_t>(i)]);
      if (!query.points_local.empty()) {
        subset.points_local.push_back(query.points_local[static_cast<size_t>(i)]);
      }
    }
    return subset;
  }
  static std::vector<int> Iota(size_t n) {
    std::vector<int> v(n);
    std::iota(v.begin(), v.end(), 0);
    return v;
  }

  // The query prepared with the camera changed by `change`; none when the
  // change makes the camera implausible.
  std::optional<PreparedQuery> Prepare(const Change& change) const {
    Query scaled = *query_;
    Camera& camera = scaled.cameras[0];
    camera.ScaleFocalLength(std::exp(change[0]));
    camera.ShiftPrincipalPoint(change[1], change[2]);
    if (change[3] != 0) camera.ScaleFocalLengthY(std::exp(change[3]));
    std::optional<PreparedQuery> prepared;
    try {
      prepared = PrepareQuery(method_, scaled, map_);
    } catch (const Error&) {
      return std::nullopt;
    }
    if (change[4] != 0 || change[5] != 0 || change[6] != 0) {
      ChangeDistortion(change[4], {change[5], change[6]}, &prepared->data);
    }
    return prepared;
  }

  Point Refit(const Change& change, const Sim3d& start) const {
    const double t2 = options_.ransac.max_error * options_.ransac.max_error;
    Point p;
    p.pose = start;
    const std::optional<PreparedQuery> prepared = Prepare(change);
    if (!prepared) {
      p.cost = std::numeric_limits<double>::infinity();
      p.squared.assign(inliers_->size(), t2);
      p.residuals.assign(inliers_->size(), Eigen::Vector2d::Zero());
      p.valid.assign(inliers_->size(), 0);
      return p;
    }
    LocalizeOptions o = options_;
    o.refine = true;
    RefineStage(method_, prepared->data, *inliers_, o, &p.pose, refine_ms_, &p.cost);
    const CameraPoses poses(prepared->data, p.pose);
    const PoseLinearization linearization(prepared->data, p.pose);
    for (const int i : *inliers_) {
      p.squared.push_back(std::min(t2, SquaredReprojectionError(prepared->data, poses, i)));
      Eigen::Vector2d r = Eigen::Vector2d::Zero();
      const int n =
          ReprojectionResidual(prepared->data, linearization, static_cast<size_t>(i), &r, nullptr);
      p.residuals.push_back(n > 0 ? r : Eigen::Vector2d::Zero());
      p.valid.push_back(n > 0 ? 1 : 0);
    }
    return p;
  }

  // Where a refit starts: the pose of the camera refitted before whose
  // change is nearest (each parameter in units of the joint fit's steps),
  // else RANSAC's.
  Sim3d NearestFit(const Change& change) const {
    const Camera& c = query_->cameras[0];
    const Change unit = JointSteps(c.width, c.height);
    const Sim3d* nearest = &start_;
    double least = std::numeric_limits<double>::infinity();
    for (const auto& [other, fit] : *fits_) {
      double d = 0;
      for (size_t k = 0; k < change.size(); ++k) d += std::pow((other[k] - change[k]) / unit[k], 2);
      if (d < least) least = d, nearest = &fit.pose;
    }
    return *nearest;
  }

  Parameter parameter_ = Parameter::kLogFocal;
  std::array<double, 3> base_ = {0, 0, 0};
  const MethodInfo& method_;
  std::shared_ptr<const Query> query_;  // shared by the copies Over / WithBase make
  const LocalizationMap& map_;
  std::shared_ptr<const std::vector<int>> inliers_;
  Sim3d start_;
  const LocalizeOptions& options_;
  double* refine_ms_;
  std::array<double, 2> radial_range_;
  std::shared_ptr<std::map<Change, Point>> fits_;  // every camera refitted, shared by the copies
};

// The calibration check as a test (Gaussian noise of unknown σ): the focal
// factor k̂ of least cost; the inliers whose error there is within the 99 %
// quantile of the noise (σ from their median: a line cloud's chance inliers,
// a band around every line, would otherwise decide); on them S(k), the sum of
// squared errors, σ̂² = S(k̂) / (rows − parameters), the standard error of
// log k̂ from the profile's curvature, var = 2 σ̂² / S''(log k̂) (the pose
// marginalised, as the profile refines it for each k), and the given focal
// length's deviance (S(0) − S(k̂)) / σ̂². On a plane seen head-on the focal
// length and the distance trade off: S is flat, the interval wide, and
// nothing is refused.
// One parameter's profile as a test: the value v̂ of least cost, its
// standard error and the given value's (v = 0) deviance (see above).
struct ProfileTest {
  double best = 0, se = std::numeric_limits<double>::infinity(), deviance = 0;
  bool at_edge = false;    // the least cost at an end of the range searched
  bool bracketed = false;  // the given value costs least of it and a step either side
  // How the pose moves with the value (per unit: log k or px), about v̂:
  // its rotation (radians, angle-axis) and its centre.
  Eigen::Vector3d rotation_rate = Eigen::Vector3d::Zero();
  Eigen::Vector3d centre_rate = Eigen::Vector3d::Zero();
};

// Clears keep[i] for the residuals beyond the 99 % quantile of the noise (σ
// from their median; χ² with 1 degree of freedom for a line, 2 for a point).
void KeepWithinNoise(const std::vector<double>& squared, int residuals_per_datum,
                     std::vector<char>* keep) {
  if (squared.empty()) return;
  const bool line = residuals_per_datum == 1;
  std::vector<double> sorted = squared;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double sigma2 = sorted[sorted.size() / 2] / (line ? 0.455 : 1.386);
  for (size_t i = 0; i < squared.size(); ++i) {
    (*keep)[i] = (*keep)[i] && squared[i] <= sigma2 * (line ? 6.63 : 9.21);
  }
}

ProfileTest TestProfile(const FocalProfile& profile, int residuals_per_datum, int pose_parameters,
                        double step) {
  ProfileTest test;
  // Searched to half the step: the parabolas below place the estimate.
  const double found = profile.Minimize(0.5 * step, step, &test.bracketed);
  test.best = profile.parameter() == FocalProfile::Parameter::kLogFocal ? std::log(found) : found;
  // The least cost at an end of the range: the camera is farther off than
  // the search reaches (a photo halved with its camera: the focal length 2x),
  // never a pass.
  test.at_edge = test.best - profile.Range()[0] < step || profile.Range()[1] - test.best < step;
  const FocalProfile::Point at = profile.At(test.best);
  if (at.squared.empty()) return test;
  // Kept: the inliers within the 99 % quantile of the noise both at v̂ and at
  // the given value, so that neither side picks the data that favour it.
  const auto within_noise = [&](const std::vector<double>& squared, std::vector<char>* keep) {
    KeepWithinNoise(squared, residuals_per_datum, keep);
  };
  const FocalProfile::Point given = profile.At(0);
  std::vector<char> kept(at.squared.size(), 1);
  within_noise(at.squared, &kept);
  within_noise(given.squared, &kept);
  int rows = 0;
  for (const char k_i : kept) rows += k_i ? residuals_per_datum : 0;
  const auto sum = [&](const FocalProfile::Point& p) {
    double s = 0;
    for (size_t i = 0; i < kept.size(); ++i) s += kept[i] ? p.squared[i] : 0.0;
    return s;
  };
  const double s_at = sum(at);
  const double s_given = sum(given);
  const FocalProfile::Point plus = profile.At(test.best + step);
  const FocalProfile::Point minus = profile.At(test.best - step);
  const double s_plus = sum(plus);
  const double s_minus = sum(minus);
  const Eigen::AngleAxisd turn(plus.pose.rotation * minus.pose.rotation.inverse());
  test.rotation_rate = turn.angle() * turn.axis() / (2 * step);
  test.centre_rate =
      (plus.pose.Inverse().translation - minus.pose.Inverse().translation) / (2 * step);
  const int dof = rows - pose_parameters - 1;
  const double curvature = (s_plus + s_minus - 2 * s_at) / (step * step);
  // The estimate: the vertex of the parabola through the three sums (the
  // search's bracket, 2 % of the focal length or 1 % of the size, is coarser
  // than the standard error on a good photo: 0.03 %, 0.2 px), then through
  // three values about it two standard errors apart: residuals clamped at the
  // threshold bend the profile within the wide stencil (fountain's principal
  // point placed 0.6 px off its finer fit, 3 standard errors). The
  // calibration's share of the uncertainty takes the estimate as the
  // camera's error; the deviance is the given camera's against the least sum
  // refitted.
  const auto vertex = [](double h, double s_m, double s_0, double s_p) {
    return std::clamp(h * (s_m - s_p) / (2 * (s_p + s_m - 2 * s_0)), -h, h);
  };
  double offset = 0, s_least = s_at;
  if (curvature > 0 && dof > 0) {
    offset = vertex(step, s_minus, s_at, s_plus);
    const double fine = std::clamp(2 * std::sqrt(2 * s_at / dof / curvature), step / 100, step / 2);
    const double centre = test.best + offset;
    const double s_centre = sum(profile.At(centre));
    const double s_right = sum(profile.At(centre + fine));
    const double s_left = sum(profile.At(centre - fine));
    s_least = std::min({s_at, s_centre, s_right, s_left});
    if (s_right + s_left - 2 * s_centre > 0) offset += vertex(fine, s_left, s_centre, s_right);
  }
  const double sigma2 = dof > 0 ? s_least / dof : 0;
  if (sigma2 > 0) test.deviance = std::max(0.0, s_given - s_least) / sigma2;
  // At an end of the range, only a significant fall in cost counts, and only
  // where the value is determined (its standard error at the given value
  // within a fifth of the range: a wall seen head-on, where the principal
  // point trades off with the position, has a flat profile that may end
  // anywhere).
  test.at_edge = test.at_edge && test.deviance > kCalibrationZ * kCalibrationZ;
  if (test.at_edge) {
    const double curvature_given =
        (sum(profile.At(step)) + sum(profile.At(-step)) - 2 * s_given) / (step * step);
    const double half_range = 0.5 * (profile.Range()[1] - profile.Range()[0]);
    test.at_edge = curvature_given > 0 &&
                   kCalibrationZ * std::sqrt(2 * sigma2 / curvature_given) <= 0.2 * half_range;
  }
  if (sigma2 > 0 && curvature > 0) {
    test.se = std::sqrt(2 * sigma2 / curvature);
    test.best += offset;
  }
  return test;
}

// The camera fitted jointly, the pose marginalised: a Gauss–Newton over θ =
// (log k, cx shift, cy shift, log aspect, radial λ, tangential p1, p2) — the
// aspect ratio only for a camera with fx and fy — on the residuals of the pose refitted for
// each θ (variable projection: the Jacobian by forward differences, each
// column one refit; IRLS weights of the refinement's Cauchy loss; a step
// kept only when the robust cost falls). One parameter at a time, the
// profiles settle in a compensating fit: a focal length 3 % short with cx 2 %
// off fitted focal +1 % and cx a further 0.8 % off, each under its limit — a
// 1.4° "success"; jointly, the fit goes back to the truth (+3.1 %, -29 px of
// -31) in 2-5 steps, 20-30 refits. And fx alone 6 % off was named a
// principal point 5 % off (its profile's deviance the largest); jointly, the
// aspect ratio takes it. Then the test, as TestProfile's: the inliers within
// the noise at both the fit and the given camera, σ̂² from the fit, the given
// camera's deviance (as many degrees of freedom as parameters) and each
// parameter's marginal standard error from σ̂² (JᵀJ)⁻¹.
JointCalibration FitCalibrationJointly(const FocalProfile& profile, int residuals_per_datum,
                                       int pose_parameters, const std::array<double, 2>& size,
                                       bool with_aspect,
                                       std::span<const std::array<double, 3>> starts,
                                       bool near_given) {
  using Theta = std::array<double, kJointParameters>;
  JointCalibration joint;
  // First the focal length and the principal point, then with the aspect
  // ratio and the distortion terms from there, each step of that stage at most 4
  // differencing steps per parameter (all five at once from the given camera
  // settled in far-off basins: the demo room's cx 5 % off became focal +7.5 %,
  // cy -12 px).
  std::vector<int> all = {0, 1, 2};
  if (with_aspect) all.push_back(3);
  all.insert(all.end(), {4, 5, 6});
  std::vector<int> active = {0, 1, 2};
  int m = 3;
  const Theta h = JointSteps(size[0], size[1]);
  std::array<std::array<double, 2>, kJointParameters> range;
  for (const int k : all) {
    range[static_cast<size_t>(k)] = profile.Over(static_cast<FocalProfile::Parameter>(k)).Range();
  }
  const auto at_theta = [&](const Theta& t) {
    return profile.AtCamera({t[0], t[1], t[2]}, t[3], t[4], {t[5], t[6]});
  };
  const double c2 = profile.loss_scale() * profile.loss_scale();
  const FocalProfile::Point given = at_theta(Theta{});
  if (given.squared.empty() || !std::isfinite(given.cost)) return joint;
  // From the start of least cost: the given camera or one of the profiles'
  // fits (the demo room's cx 5 % off, its focal length refined: from the
  // given camera the descent settled at focal +8 %, cy -12 px).
  Theta theta{};
  FocalProfile::Point at = given;
  for (const std::array<double, 3>& start : starts) {
    const Theta t = {start[0], start[1], start[2], 0, 0, 0, 0};
    FocalProfile::Point q = at_theta(t);
    if (q.cost < at.cost && q.valid.size() == given.valid.size()) theta = t, at = std::move(q);
  }
  const size_t n = given.residuals.size();
  Eigen::MatrixXd jacobian;
  std::vector<char> usable(n, 1);
  Theta linearized_at = theta;
  const auto linearize = [&]() {
    linearized_at = theta;
    jacobian.resize(static_cast<Eigen::Index>(2 * n), m);
    std::fill(usable.begin(), usable.end(), 1);
    for (int c = 0; c < m; ++c) {
      const size_t k = static_cast<size_t>(active[static_cast<size_t>(c)]);
      Theta moved = theta;
      moved[k] += h[k];
      const FocalProfile::Point q = at_theta(moved);
      for (size_t i = 0; i < n; ++i) {
        usable[i] = usable[i] && at.valid[i] && q.valid[i];
        jacobian.block<2, 1>(static_cast<Eigen::Index>(2 * i), c) =
            (q.residuals[i] - at.residuals[i]) / h[k];
      }
    }
  };
  // Σ over the usable rows of w JᵢᵀJᵢ (and w Jᵢᵀrᵢ), w per datum.
  const auto normal_equations = [&](const std::vector<double>& w, Eigen::MatrixXd* a,
                                    Eigen::VectorXd* b) {
    *a = Eigen::MatrixXd::Zero(m, m);
    *b = Eigen::VectorXd::Zero(m);
    for (size_t i = 0; i < n; ++i) {
      if (!usable[i] || w[i] == 0) continue;
      const Eigen::MatrixXd j = jacobian.middleRows(static_cast<Eigen::Index>(2 * i), 2);
      a->noalias() += w[i] * j.transpose() * j;
      b->noalias() += w[i] * j.transpose() * at.residuals[i];
    }
  };
  // A camera whose every profile found the given value best between its
  // steps (near_given) goes to all parameters at once: the first stage
  // guards against far-off basins, and there it only polished the three
  // (fountain 0005: 13 of the fit's 38 refits, moving them 0.1 % and 0.7 px).
  for (int stage = near_given ? 1 : 0; stage < 2; ++stage) {
    if (stage == 1) {
      if (all.size() == active.size()) break;
      active = all;
      m = static_cast<int>(active.size());
    }
    for (int iteration = 0; iteration < 8; ++iteration) {
      linearize();
      std::vector<double> w(n);
      for (size_t i = 0; i < n; ++i) w[i] = 1.0 / (1.0 + at.residuals[i].squaredNorm() / c2);
      Eigen::MatrixXd a;
      Eigen::VectorXd b;
      normal_equations(w, &a, &b);
      Eigen::VectorXd step = -a.ldlt().solve(b);
      if (!step.allFinite()) break;
      if (stage == 1) {
        double largest = 0;
        for (int c = 0; c < m; ++c) {
          largest = std::max(
              largest, std::abs(step[c]) / h[static_cast<size_t>(active[static_cast<size_t>(c)])]);
        }
        if (largest > 4) step *= 4 / largest;
      }
      // The step, halved until the cost falls (at most 3 times); a full step
      // taken is repeated along the same direction while the cost falls (the
      // IRLS steps fall short by about half when many residuals sit in the
      // loss's tail).
      const auto take = [&](const Eigen::VectorXd& delta) {
        Theta candidate = theta;
        for (int c = 0; c < m; ++c) {
          const size_t k = static_cast<size_t>(active[static_cast<size_t>(c)]);
          candidate[k] = std::clamp(theta[k] + delta[c], range[k][0], range[k][1]);
        }
        FocalProfile::Point q = at_theta(candidate);
        if (!(q.cost < at.cost)) return false;
        theta = candidate, at = std::move(q);
        return true;
      };
      int halvings = 0;
      while (halvings < 4 && !take(step)) step *= 0.5, ++halvings;
      if (halvings == 4) break;
      int longer = 0;
      while (halvings == 0 && longer < 3 && take(step)) ++longer;
      bool small = true;
      for (int c = 0; c < m; ++c) {
        small = small &&
                std::abs(step[c]) < 0.05 * h[static_cast<size_t>(active[static_cast<size_t>(c)])];
      }
      if (small) break;
    }
  }
  // The standard errors at the fit: the last Jacobian when the fit has moved
  // less than a twentieth of each step since (7 refits).
  bool moved = false;
  for (const int k : active) {
    const size_t i = static_cast<size_t>(k);
    moved = moved || std::abs(theta[i] - linearized_at[i]) >= 0.05 * h[i];
  }
  if (moved || jacobian.cols() != m) linearize();
  std::vector<char> kept(n, 1);
  KeepWithinNoise(at.squared, residuals_per_datum, &kept);
  KeepWithinNoise(given.squared, residuals_per_datum, &kept);
  double s_at = 0, s_given = 0;
  int rows = 0;
  std::vector<double> w(n, 0.0);
  for (size_t i = 0; i < n; ++i) {
    if (!kept[i]) continue;
    s_at += at.squared[i];
    s_given += given.squared[i];
    rows += residuals_per_datum;
    w[i] = 1;
  }
  const int dof = rows - pose_parameters - m;
  if (dof <= 0 || !(s_at > 0)) return joint;
  const double sigma2 = s_at / dof;
  joint.fitted = true;
  joint.parameters = m;
  joint.theta = theta;
  for (const int k : active) joint.active[static_cast<size_t>(k)] = true;
  joint.deviance = std::max(0.0, s_given - s_at) / sigma2;
  joint.pose_shift_deg =
      Eigen::AngleAxisd(at.pose.rotation * given.pose.rotation.inverse()).angle() * 180 /
      std::numbers::pi;
  joint.pose_shift_centre =
      (at.pose.Inverse().translation - given.pose.Inverse().translation).norm();
  Eigen::MatrixXd information;
  Eigen::VectorXd unused;
  normal_equations(w, &information, &unused);
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(information);
  if (ldlt.info() == Eigen::Success && ldlt.isPositive()) {
    const Eigen::MatrixXd covariance = sigma2 * ldlt.solve(Eigen::MatrixXd::Identity(m, m));
    // How much wider the standard errors are when the fit's Wald statistic
    // θᵀ C⁻¹ θ is brought down to its deviance: the robust cost is flatter
    // than its curvature at the fit says (residuals in the loss's tail). True
    // cameras on fountain, 42 keys x 3 maps: cy +12 px at "4.6 σ", p1 +0.0029
    // at "3.9 σ" with a deviance of 10 for all seven parameters together.
    Eigen::VectorXd t(m);
    for (int c = 0; c < m; ++c) t[c] = theta[static_cast<size_t>(active[static_cast<size_t>(c)])];
    const double wald = t.dot(information * t) / sigma2;
    if (wald > joint.deviance) joint.se_scale = std::sqrt(wald / std::max(joint.deviance, 1.0));
    for (int c = 0; c < m; ++c) {
      if (covariance(c, c) > 0) {
        joint.se[static_cast<size_t>(active[static_cast<size_t>(c)])] = std::sqrt(covariance(c, c));
      }
    }
  }
  return joint;
}

// Whether the camera's model has fx and fy apart (its aspect ratio can be wrong).
bool SeparateFocalLengths(const Camera& camera) {
  Camera stretched = camera;
  stretched.ScaleFocalLengthY(2);
  return stretched.FocalLengthY() != camera.FocalLengthY();
}

// The mean square error of a given calibration value, a prior N(0, prior²)
// on its error (the camera as given is trusted to that) and the profile's
// estimate of it (best ± se) combined: the posterior's mean² + variance.
// A flat profile (se = ∞) leaves the prior; a sharp one gives best² + se².
double CalibrationMeanSquare(const ProfileTest& test, double prior) {
  if (!(prior > 0)) return 0;
  if (!std::isfinite(prior) || test.at_edge) return test.se * test.se + test.best * test.best;
  if (!std::isfinite(test.se)) return prior * prior;
  const double p2 = prior * prior, s2 = test.se * test.se;
  const double mean = test.best * p2 / (p2 + s2);
  return mean * mean + p2 * s2 / (p2 + s2);
}

// The pose's uncertainty from the calibration: each parameter's mean square
// error (above) through the pose's rate of change with it, added to the
// squared RMS rotation (degrees) and centre uncertainty.
void AddCalibrationUncertainty(const ProfileTest& test, double prior, CalibrationCheck* check) {
  const double ms = CalibrationMeanSquare(test, prior);
  const double rotation_deg = test.rotation_rate.norm() * 180 / std::numbers::pi;
  check->rotation_deg = std::hypot(check->rotation_deg, rotation_deg * std::sqrt(ms));
  check->position = std::hypot(check->position, test.centre_rate.norm() * std::sqrt(ms));
}

// prior_log_focal / prior_principal (a fraction of the image's size): how far
// the camera as given is trusted (1 σ); +∞ for a focal length refined.
// *near_given: every profile (focal length, cx, cy) found the given value
// best between its steps either side — a camera near its best fit.
CalibrationCheck CheckCalibration(const FocalProfile& profile, int residuals_per_datum,
                                  int pose_parameters, double given_focal, const Camera& camera,
                                  double prior_log_focal, double prior_principal,
                                  bool* near_given) {
  CalibrationCheck check;
  const ProfileTest focal =
      TestProfile(profile, residuals_per_datum, pose_parameters, /*step=*/0.02);
  AddCalibrationUncertainty(focal, prior_log_focal, &check);
  check.best_fit_focal = std::exp(focal.best) * given_focal;
  *near_given = focal.bracketed;
  check.at_edge[0] = focal.at_edge;
  if (std::isfinite(focal.se)) {
    check.log_focal_se = focal.se;
    check.interval = {check.best_fit_focal * std::exp(-kCalibrationZ * focal.se),
                      check.best_fit_focal * std::exp(kCalibrationZ * focal.se)};
    check.deviance = focal.deviance;
  }
  const Eigen::Vector2d c = camera.PrincipalPoint();
  check.given_principal = {c.x(), c.y()};
  check.image_size = {static_cast<double>(camera.width), static_cast<double>(camera.height)};
  for (int axis = 0; axis < 2; ++axis) {
    const double size = check.image_size[axis];
    const ProfileTest shift =
        TestProfile(profile.Over(axis == 0 ? FocalProfile::Parameter::kPrincipalX
                                           : FocalProfile::Parameter::kPrincipalY),
                    residuals_per_datum, pose_parameters, /*step=*/0.01 * size);
    AddCalibrationUncertainty(shift, prior_principal * size, &check);
    check.best_fit_principal[axis] = check.given_principal[axis] + shift.best;
    check.at_edge[static_cast<size_t>(1 + axis)] = shift.at_edge;
    check.principal_se[axis] = shift.se;
    check.principal_deviance[axis] = shift.deviance;
    *near_given = *near_given && shift.bracketed;
  }
  return check;
}

// The aspect ratio (when fy can change alone) and the radial distortion,
// profiled on `profile`'s camera, into `check` (their share of the
// uncertainty too): trusted to 1 % and 0.02 (1 σ a third of that). With the
// focal length refined, judged at the focal length and principal point fitted
// jointly from the camera as given: the refined focal length and its pose
// absorbed an fy 5 % off (its profile then moved by 0.3 %: a 2.8° "success"),
// and the camera as given puts a focal length 20 % off into k1.
void CheckAspectAndDistortion(const FocalProfile& profile, int residuals_per_datum,
                              int pose_parameters, const Camera& camera, CalibrationCheck* check) {
  const auto extra = [&](FocalProfile::Parameter p, double step, double prior,
                         CalibrationCheck::Extra* out) {
    const ProfileTest t = TestProfile(profile.Over(p), residuals_per_datum, pose_parameters, step);
    AddCalibrationUncertainty(t, prior, check);
    *out = {true, t.best, t.se, t.deviance, t.at_edge};
  };
  if (SeparateFocalLengths(camera)) {
    extra(FocalProfile::Parameter::kLogAspect, 0.01, 0.01 / kCalibrationZ, &check->log_aspect);
  }
  extra(FocalProfile::Parameter::kRadial, 0.02, 0.02 / kCalibrationZ, &check->radial);
}

}  // namespace

namespace {

// The query without the observations that cannot be undistorted; kept[i] is
// the original index of observation i.
Query UsableObservations(const Query& query, std::vector<int>* kept) {
  Query usable = query;
  usable.observations.clear();
  usable.points_local.clear();
  kept->clear();
  for (size_t i = 0; i < query.observations.size(); ++i) {
    const QueryObservation& o = query.observations[i];
    if (!query.cameras[static_cast<size_t>(o.camera)].CanUndistort(o.xy)) continue;
    kept->push_back(static_cast<int>(i));
    usable.observations.push_back(o);
    if (!query.points_local.empty()) usable.points_local.push_back(query.points_local[i]);
  }
  return usable;
}

// Inliers the calibration check fits the focal length to, at most.
constexpr size_t kCheckInliers = 300;

LocalizeResult LocalizeUsable(const MethodInfo& method, const Query& query,
                              const LocalizationMap& map, const LocalizeOptions& options,
                              std::string_view source, std::span<const int> kept) {
  if (options.refine_focal && query.cameras.size() != 1) {
    Fail("{}: refining the focal length needs a query with one camera, got {}", source,
         query.cameras.size());
  }
  const auto prepare_start = std::chrono::steady_clock::now();
  PreparedQuery prepared = PrepareCheckedQuery(method, query, map, source, kept);
  LocalizeResult result;
  result.prepare_ms = MsSince(prepare_start);
  result.num_correspondences = static_cast<int>(query.observations.size());
  PoseEstimator estimator(method, prepared.data, options.local_refinement);
  // With a ranking, PROSAC then its competitor search (ransac.h). The search
  // for a model ends once one with the support the criteria need could not
  // have been missed.
  RansacOptions ransac_options = options.ransac;
  const int n = static_cast<int>(prepared.data.size());
  ransac_options.min_support = std::max(
      method.lines ? options.success.min_inliers_lines : options.success.min_inliers_points,
      static_cast<int>(std::ceil(options.success.min_inlier_ratio * n)));
  RansacResult<Sim3d> ransac = Ransac(estimator, ransac_options, prepared.data.ranking);
  result.stats = ransac.stats;
  if (ransac.stats.runner_up_inliers > 0) {
    result.runner_up_rotation_deg =
        ransac.model.rotation.angularDistance(ransac.runner_up.rotation) * 180 / M_PI;
  }
  const std::string_view stop = ransac.stats.stop_reason;
  if (stop == "stopped") {
    result.failure = "stopped by the caller";
    return result;
  }
  if (stop == "max_seconds" && ransac.stats.iterations < options.ransac.min_iterations) {
    // A pose from fewer draws than the floor is not trusted, whatever its inliers.
    result.failure = fmt::format(
        "the time allowed ({:g} s for RANSAC) ran out before the matches could be judged; allow "
        "more time",
        options.ransac.max_seconds);
    return result;
  }
  if (!ransac.success) {
    result.failure = fmt::format(
        "no pose fits the {} matches{}; a photo of another place, or a wrong camera, looks like "
        "this",
        n, stop == "max_seconds" ? " within the time allowed" : "");
    return result;
  }
  std::vector<int> ransac_inliers;
  InlierIndices(ransac.inlier_mask, &ransac_inliers);
  const std::vector<int> first_inliers = ransac_inliers;  // both reprojection means use these
  result.reprojection_initial_px =
      MeanReprojectionError(prepared.data, ransac.model, first_inliers);
  Sim3d pose = ransac.model;
  result.given_focal = query.cameras[0].MeanFocalLength();
  Query scaled = query;  // the camera as given, or with its focal length refined
  if (options.refine_focal) {
    // Focal length and inliers in turn: the inliers RANSAC found with the
    // prior focal length are a subset of those the refined one explains.
    for (int round = 0; round < 3; ++round) {
      const double k =
          FocalProfile(method, scaled, map, ransac_inliers, pose, options, &result.refine_ms)
              .Minimize(/*tolerance=*/1e-4);
      scaled.cameras[0].ScaleFocalLength(k);
      CheckQuery(method, scaled, source);  // the rescaled camera is checked anew, as before
      prepared = PrepareCheckedQuery(method, scaled, map, source, kept);
      RefineStage(method, prepared.data, ransac_inliers, options, &pose, &result.refine_ms,
                  nullptr);
      std::vector<char> mask;
      PoseEstimator(method, prepared.data, options.local_refinement)
          .inliers(pose, options.ransac.max_error, &mask);
      InlierIndices(mask, &ransac_inliers);
      if (std::abs(std::log(k)) < 1e-3) break;
    }
    result.refined_focal = scaled.cameras[0].MeanFocalLength();
  }
  if ((options.success.max_focal_discrepancy > 0 ||
       options.success.max_principal_discrepancy > 0) &&
      query.cameras.size() == 1 &&
      ransac_inliers.size() > static_cast<size_t>(method.sample_size) + 1) {
    // The calibration check: the focal length and the principal point the
    // inliers fit best — after a focal refinement too, so that refining the
    // focal length never turns a wrong principal point into a "success". A
    // check against a 10 % discrepancy needs neither every inlier nor 0.01 %:
    // at most kCheckInliers of them, evenly spaced; the searches to 1 % in k
    // and 0.5 % of the image in the principal point, the parabola through the
    // last three sums placing the estimate finer (TestProfile).
    const auto check_start = std::chrono::steady_clock::now();
    double unused_ms = 0;
    std::vector<int> check_inliers;
    const size_t m = ransac_inliers.size();
    for (size_t i = 0; i < std::min(m, kCheckInliers); ++i) {
      check_inliers.push_back(ransac_inliers[i * m / std::min(m, kCheckInliers)]);
    }
    const double focal = scaled.cameras[0].MeanFocalLength();
    // The camera as given is trusted to 1 % in its focal length (a
    // calibration, or EXIF with a known sensor) and to a third of what the
    // check lets through in its principal point; a refined focal length only
    // to its profile (on a wall seen head-on, where the focal length and the
    // distance trade off, the position is then undetermined).
    const SuccessCriteria& c = options.success;
    const FocalProfile profile(method, scaled, map, check_inliers, pose, options, &unused_ms);
    bool near_given = false;
    const int residuals_per_datum = method.lines ? 1 : 2;
    const int pose_parameters = method.similarity() ? 7 : 6;
    CalibrationCheck& check = result.calibration_check.emplace(
        CheckCalibration(profile, residuals_per_datum, pose_parameters, focal, scaled.cameras[0],
                         options.refine_focal ? std::numeric_limits<double>::infinity() : 0.01,
                         c.max_principal_discrepancy / kCalibrationZ, &near_given));
    if (options.refine_focal) {  // the refined focal length is the one checked: not refused
      check.best_fit_focal = focal;
      check.deviance = 0;
      // A refined focal length and the pose absorb much of a wrong principal
      // point (cx 5 % off: focal -2.5 %, a 1.6° "success", the principal
      // point then 5 px from where the profile puts it). Fitted jointly from
      // the camera as given, the principal point shows (FitCalibrationJointly).
      const FocalProfile given_camera(method, query, map, check_inliers, ransac.model, options,
                                      &unused_ms);
      check.joint =
          FitCalibrationJointly(given_camera, residuals_per_datum, pose_parameters,
                                check.image_size, SeparateFocalLengths(query.cameras[0]),
                                ProfileStarts(check, focal, result.given_focal), near_given);
      check.refit_principal =
          std::array<double, 2>{check.given_principal[0] + check.joint.theta[1],
                                check.given_principal[1] + check.joint.theta[2]};
      const std::array<double, 3> fitted = {check.joint.theta[0], check.joint.theta[1],
                                            check.joint.theta[2]};
      CheckAspectAndDistortion(given_camera.WithBase(fitted), residuals_per_datum, pose_parameters,
                               query.cameras[0], &check);
    } else {
      check.joint =
          FitCalibrationJointly(profile, residuals_per_datum, pose_parameters, check.image_size,
                                SeparateFocalLengths(scaled.cameras[0]),
                                ProfileStarts(check, focal, result.given_focal), near_given);
      CheckAspectAndDistortion(profile, residuals_per_datum, pose_parameters, scaled.cameras[0],
                               &check);
    }
    result.best_fit_focal = result.calibration_check->best_fit_focal;
    result.check_ms += MsSince(check_start);
  }
  result.refine_iterations = RefineStage(method, prepared.data, ransac_inliers, options, &pose,
                                         &result.refine_ms, nullptr);
  std::vector<char> mask;
  const PoseEstimator final_inliers(method, prepared.data, options.local_refinement);
  final_inliers.inliers(pose, options.ransac.max_error, &mask);
  InlierIndices(mask, &result.inliers);
  // Refined again on the refined pose's inliers until they stop changing (at
  // most two more rounds): the pose should not depend on how rough RANSAC's
  // model was. A progressive run may stop after three samples; a +l model
  // comes from the local points, not the pixels: inliers chosen at it leave
  // out true ones on one side (m-P3P+l at 0.5 % local noise: 3-4 sigma off).
  // Rounds cost nothing once the inliers are stable.
  const int extra_rounds = 2;
  for (int round = 0; round < extra_rounds && options.refine && result.inliers != ransac_inliers;
       ++round) {
    ransac_inliers = result.inliers;
    result.refine_iterations += RefineStage(method, prepared.data, ransac_inliers, options, &pose,
                                            &result.refine_ms, nullptr);
    final_inliers.inliers(pose, options.ransac.max_error, &mask);
    InlierIndices(mask, &result.inliers);
  }
  result.reprojection_refined_px = MeanReprojectionError(prepared.data, pose, first_inliers);
  result.query_from_world = prepared.ToQueryFromWorld(pose);
  result.initial = prepared.ToQueryFromWorld(ransac.model);
  result.has_pose = true;
  const auto uncertainty_start = std::chrono::steady_clock::now();
  if (method.local_points && method.similarity() && options.refine &&
      SeenByOneCamera(prepared.data, result.inliers)) {
    // The reprojections leave the scale free: the local points give it.
    result.local_scale = FitScaleToLocalPoints(prepared.data, result.inliers, &pose);
    if (result.local_scale) result.query_from_world = prepared.ToQueryFromWorld(pose);
  }
  result.uncertainty =
      EstimatePoseUncertainty(prepared.data, result.inliers, pose, method.similarity(),
                              result.local_scale ? result.local_scale->sigma_local : 0.0);
  result.matches_uncertainty = result.uncertainty;
  if (result.calibration_check) {  // the calibration's share: independent of the matches' noise
    result.inlier_distance = MedianInlierDistance(prepared.data, result.inliers, pose);
    // A camera the data reject as a whole (each parameter within its limit):
    // the pose at the camera they fit best is where this one may be, so the
    // move to it counts in the calibration's share (entry 0008, focal x0.97
    // with cx +2 %: deviance 1 340, every parameter of the joint fit under
    // its limit, a 1.3° "success" with σ 0.63°).
    // (With the focal length refined the joint fit starts from the camera as
    // given, not the one the pose was found with: not counted.)
    CalibrationCheck& check = *result.calibration_check;
    if (!check.refit_principal && check.joint.RejectsGiven()) {
      check.rotation_deg = std::hypot(check.rotation_deg, check.joint.pose_shift_deg);
      check.position = std::hypot(check.position, check.joint.pose_shift_centre);
    }
    result.uncertainty.rotation_deg =
        std::hypot(result.uncertainty.rotation_deg, result.calibration_check->rotation_deg);
    result.uncertainty.position =
        std::hypot(result.uncertainty.position, result.calibration_check->position);
  }
  result.check_ms += MsSince(uncertainty_start);
  return result;
}

// A camera that does not fit its photo, as the reason, or "": a principal
// point outside its image (a photo downscaled or cropped after its
// calibration keeps its camera's: fountain at 640 px with the 1536 px camera
// was a 29° "success"), a photo turned with only the camera's width and
// height swapped, or a camera made for the photo at 1.8 times its size or
// more (a photo halved with its camera was a 24° "success", its inliers
// explained by a focal length twice too long) — unless the principal point is
// not checked (max_principal_discrepancy 0). A camera that only looks made
// for a size less far off is left to the calibration check, which names the
// mistake when it refuses: an off-centre crop sent with its true camera looks
// the same (a 900x600 crop of fountain's top left: "made for 1.7 times this
// size"), and was refused before any work.
std::string CameraDoesNotFitPhoto(const Query& query, const SuccessCriteria& criteria) {
  for (size_t c = 0; c < query.cameras.size(); ++c) {
    const Camera& camera = query.cameras[c];
    const Eigen::Vector2d pp = camera.PrincipalPoint();
    const bool outside =
        !(pp.x() >= 0 && pp.x() <= camera.width && pp.y() >= 0 && pp.y() <= camera.height);
    const std::string hint = CameraMistakeHint(camera);
    const double factor = SizeFactor(
        {static_cast<double>(camera.width), static_cast<double>(camera.height)}, {pp.x(), pp.y()});
    const bool beyond_check = factor == 0 || std::abs(std::log(factor)) >= std::log(1.8);
    if (!outside && (hint.empty() || !beyond_check || !(criteria.max_principal_discrepancy > 0))) {
      continue;
    }
    return fmt::format(
        "the camera{} does not fit its photo: its principal point ({:.0f}, {:.0f}) is {} the "
        "{}x{} image; {}",
        query.cameras.size() > 1 ? fmt::format(" {}", c) : "", pp.x(), pp.y(),
        outside ? "outside" : "far from the centre of", camera.width, camera.height,
        hint.empty() ? "a photo downscaled or cropped after its calibration looks like this: "
                       "scale or shift the camera with the photo"
                     : hint);
  }
  return "";
}

}  // namespace

LocalizeResult Localize(const MethodInfo& method, const Query& query, const LocalizationMap& map,
                        const LocalizeOptions& options, std::string_view source) {
  options.Check();
  CheckMethodAndMap(method, map);
  if (std::string outside = CameraDoesNotFitPhoto(query, options.success); !outside.empty()) {
    LocalizeResult refused;  // before the camera's other checks: the mistake to name
    refused.num_correspondences = static_cast<int>(query.observations.size());
    refused.failure = std::move(outside);
    return refused;
  }
  CheckQuery(method, query, source);
  std::vector<int> kept;
  const Query usable = UsableObservations(query, &kept);
  LocalizeResult result = LocalizeUsable(method, usable, map, options, source, kept);
  // Indices and counts refer to the query as given; rejected observations
  // count against the inlier ratio.
  result.num_correspondences = static_cast<int>(query.observations.size());
  result.rejected_observations = static_cast<int>(query.observations.size() - kept.size());
  for (int& i : result.inliers) i = kept[static_cast<size_t>(i)];
  if (query.cameras.size() > 1) {
    result.camera_observations.assign(query.cameras.size(), 0);
    result.camera_inliers.assign(query.cameras.size(), 0);
    for (const QueryObservation& o : query.observations) ++result.camera_observations[o.camera];
    for (const int i : result.inliers) ++result.camera_inliers[query.observations[i].camera];
  }
  if (result.has_pose) {
    result.failure = SuccessFailure(method, result, options.success);
    result.success = result.failure.empty();
  }
  if (!result.success && query.cameras.size() == 1) {
    // Whatever refused the pose, a camera that shows a common mistake is
    // named too (a turned photo often keeps too few inliers to be judged).
    const std::string hint = CameraMistakeHint(query.cameras[0]);
    if (!hint.empty() && result.failure.find(hint) == std::string::npos) {
      result.failure += "; also, " + hint;
    }
  }
  return result;
}

}  // namespace linecloud
