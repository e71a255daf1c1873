#include "linecloud/localize/query_json.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "linecloud/io/json_util.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

const nlohmann::json& Array(const nlohmann::json& j, const char* name, const std::string& source) {
  if (!j.contains(name)) Fail("{}: field '{}' is missing", source, name);
  if (!j[name].is_array()) Fail("{}: '{}' must be an array", source, name);
  return j[name];
}

}  // namespace

Camera CameraFromJson(const nlohmann::json& j, const std::string& where) {
  if (!j.is_object()) Fail("{}: expected an object", where);
  // A misspelt or unsupported field is refused rather than ignored (first, so that "Model" is
  // named as what it is, not as a missing "model"); the identity fields of COLMAP's and
  // pycolmap's camera dicts are accepted (and not used).
  for (const auto& [key, value] : j.items()) {
    static constexpr std::string_view kKnown[] = {
        "model", "width", "height", "params", "id", "camera_id", "has_prior_focal_length"};
    if (std::find(std::begin(kKnown), std::end(kKnown), key) == std::end(kKnown)) {
      Fail("{}: unknown field {} (model, width, height, params)", where, ShownInMessage(key));
    }
  }
  for (const char* key : {"model", "width", "height", "params"}) {
    if (!j.contains(key)) Fail("{}: field '{}' is missing", where, key);
  }
  if (!j["model"].is_string()) Fail("{}.model: expected a camera model name", where);
  Camera camera;
  const std::string model = j["model"].get<std::string>();
  camera.model_id = CameraModelFromName(model);
  if (camera.model_id == CameraModelId::kInvalid) {
    Fail(
        "{}.model: unknown camera model '{}' (COLMAP models 0-6: SIMPLE_PINHOLE, PINHOLE, "
        "SIMPLE_RADIAL, RADIAL, OPENCV, OPENCV_FISHEYE, FULL_OPENCV)",
        where, model);
  }
  for (const char* key : {"width", "height"}) {
    if (!j[key].is_number_unsigned()) Fail("{}.{}: expected a positive integer", where, key);
  }
  camera.width = j["width"].get<uint64_t>();
  camera.height = j["height"].get<uint64_t>();
  if (!j["params"].is_array()) Fail("{}.params: expected an array of numbers", where);
  for (size_t i = 0; i < j["params"].size(); ++i) {
    if (!j["params"][i].is_number()) Fail("{}.params[{}]: not a number", where, i);
    camera.params.push_back(j["params"][i].get<double>());
  }
  camera.Check(where);
  return camera;
}

nlohmann::json CameraToJson(const Camera& camera) {
  return {{"model", std::string(CameraModelName(camera.model_id))},
          {"width", camera.width},
          {"height", camera.height},
          {"params", camera.params}};
}

Query ParseQueryJson(const nlohmann::json& j, const std::string& source) {
  if (!j.is_object()) Fail("{}: expected a JSON object", source);
  Query q;
  const nlohmann::json& cameras = Array(j, "cameras", source);
  for (size_t c = 0; c < cameras.size(); ++c) {
    q.cameras.push_back(CameraFromJson(cameras[c], fmt::format("{}: cameras[{}]", source, c)));
  }
  if (j.contains("cam_from_rig")) {
    const nlohmann::json& poses = Array(j, "cam_from_rig", source);
    for (size_t c = 0; c < poses.size(); ++c) {
      q.cam_from_rig.push_back(JsonPose(poses[c], fmt::format("{}: cam_from_rig[{}]", source, c)));
    }
  }
  const nlohmann::json& observations = Array(j, "observations", source);
  for (size_t i = 0; i < observations.size(); ++i) {
    const std::string where = fmt::format("{}: observations[{}]", source, i);
    const nlohmann::json& o = observations[i];
    if (!o.is_object() || !o.contains("xy") || !o.contains("id")) {
      Fail("{}: expected {{\"camera\": c, \"xy\": [u, v], \"id\": n}}", where);
    }
    QueryObservation obs;
    if (o.contains("camera")) {
      // Range-checked: 4294967296 must not wrap to camera 0.
      if (!o["camera"].is_number_integer() || o["camera"].get<int64_t>() < 0 ||
          o["camera"].get<int64_t>() > std::numeric_limits<int>::max()) {
        Fail("{}.camera: expected a camera index (a non-negative integer)", where);
      }
      obs.camera = static_cast<int>(o["camera"].get<int64_t>());
    }
    if (!o["id"].is_number_unsigned()) Fail("{}.id: expected a non-negative integer", where);
    obs.id = o["id"].get<uint64_t>();
    if (o.contains("line_id")) {
      if (!o["line_id"].is_number_unsigned()) {
        Fail("{}.line_id: expected a non-negative integer", where);
      }
      obs.line_id = o["line_id"].get<uint64_t>();
    }
    if (o.contains("ratio")) {
      if (!o["ratio"].is_number() || !std::isfinite(o["ratio"].get<double>()) ||
          o["ratio"].get<double>() < 0) {
        Fail("{}.ratio: expected a match's Lowe ratio (a finite number >= 0)", where);
      }
      obs.match_ratio = o["ratio"].get<double>();
    }
    const nlohmann::json& xy = o["xy"];
    if (!xy.is_array() || xy.size() != 2 || !xy[0].is_number() || !xy[1].is_number()) {
      Fail("{}.xy: expected [u, v]", where);
    }
    obs.xy = Eigen::Vector2d(xy[0].get<double>(), xy[1].get<double>());
    if (!obs.xy.allFinite()) Fail("{}.xy: not finite", where);
    q.observations.push_back(obs);
  }
  if (j.contains("points_local")) {
    q.points_local = JsonVector3List(j["points_local"], source + ": points_local");
  }
  if (j.contains("gravity_query")) {
    q.gravity_query = JsonVector3(j["gravity_query"], source + ": gravity_query");
  }
  if (j.contains("gravity_map")) {
    q.gravity_map = JsonVector3(j["gravity_map"], source + ": gravity_map");
  }
  return q;
}

Query ReadQueryJson(const std::string& path) { return ParseQueryJson(ReadJsonFile(path), path); }

std::vector<LocalPoint> ParseLocalPointsJson(const nlohmann::json& j, const std::string& where) {
  if (!j.is_array()) {
    Fail("{}: expected [{{\"frame\": k, \"keypoint\": i, \"xyz\": [x, y, z]}}, ...]", where);
  }
  std::vector<LocalPoint> points;
  points.reserve(j.size());
  for (size_t i = 0; i < j.size(); ++i) {
    const std::string at = fmt::format("{}[{}]", where, i);
    const nlohmann::json& e = j[i];
    if (!e.is_object()) Fail("{}: expected {{\"frame\", \"keypoint\", \"xyz\"}}", at);
    RefuseUnknownFields(e, {"frame", "keypoint", "xyz"}, at);
    LocalPoint p;
    for (const char* key : {"frame", "keypoint"}) {
      if (!e.contains(key)) Fail("{}: field '{}' is missing", at, key);
      if (!e[key].is_number_integer() || e[key].get<int64_t>() < 0 ||
          e[key].get<int64_t>() > (int64_t{1} << 31)) {
        Fail("{}.{}: expected an index (0, 1, ...)", at, key);
      }
    }
    p.frame = static_cast<int>(e["frame"].get<int64_t>());
    p.keypoint = e["keypoint"].get<int64_t>();
    if (!e.contains("xyz")) Fail("{}: field 'xyz' is missing", at);
    p.xyz = JsonVector3(e["xyz"], at + ".xyz");
    if (!p.xyz.allFinite()) Fail("{}.xyz: not finite", at);
    points.push_back(p);
  }
  return points;
}

nlohmann::json LocalPointsToJson(std::span<const LocalPoint> points) {
  nlohmann::json j = nlohmann::json::array();
  for (const LocalPoint& p : points) {
    j.push_back(
        {{"frame", p.frame}, {"keypoint", p.keypoint}, {"xyz", {p.xyz.x(), p.xyz.y(), p.xyz.z()}}});
  }
  return j;
}

RigFile ParseRigJson(const nlohmann::json& j, const std::string& where) {
  if (!j.is_object() || !j.contains("cam_from_rig") || !j["cam_from_rig"].is_array() ||
      j["cam_from_rig"].empty()) {
    Fail("{}: expected {{\"cam_from_rig\": [{{\"q\": [w, x, y, z], \"t\": [x, y, z]}}, ...]}}",
         where);
  }
  RefuseUnknownFields(j, {"cam_from_rig", "points_local", "scale_known", "gravity"}, where);
  RigFile rig;
  for (size_t i = 0; i < j["cam_from_rig"].size(); ++i) {
    rig.cam_from_rig.push_back(
        JsonPose(j["cam_from_rig"][i], fmt::format("{}: cam_from_rig[{}]", where, i)));
  }
  if (j.contains("points_local")) {
    rig.points_local = ParseLocalPointsJson(j["points_local"], where + ": points_local");
  }
  if (j.contains("scale_known")) {
    if (!j["scale_known"].is_boolean()) Fail("{}: scale_known: expected true or false", where);
    rig.scale_known = j["scale_known"].get<bool>();
  }
  if (j.contains("gravity")) {
    rig.gravity = JsonVector3(j["gravity"], where + ": gravity");
    if (!(rig.gravity->allFinite() && rig.gravity->cwiseAbs().maxCoeff() > 0)) {
      Fail("{}: gravity must be a finite non-zero direction", where);
    }
  }
  return rig;
}

RigFile ReadRigJson(const std::string& path) { return ParseRigJson(ReadJsonFile(path), path); }

nlohmann::json QueryToJson(const Query& q) {
  nlohmann::json j;
  j["cameras"] = nlohmann::json::array();
  for (const Camera& c : q.cameras) {
    j["cameras"].push_back(CameraToJson(c));
  }
  if (!q.cam_from_rig.empty()) {
    j["cam_from_rig"] = nlohmann::json::array();
    for (const Rigid3d& p : q.cam_from_rig) {
      j["cam_from_rig"].push_back(PoseToJson(p.rotation, p.translation));
    }
  }
  j["observations"] = nlohmann::json::array();
  for (const QueryObservation& o : q.observations) {
    j["observations"].push_back({{"camera", o.camera}, {"xy", {o.xy.x(), o.xy.y()}}, {"id", o.id}});
    if (o.line_id) j["observations"].back()["line_id"] = *o.line_id;
    if (o.match_ratio) j["observations"].back()["ratio"] = *o.match_ratio;
  }
  if (!q.points_local.empty()) {
    j["points_local"] = nlohmann::json::array();
    for (const Eigen::Vector3d& p : q.points_local) {
      j["points_local"].push_back({p.x(), p.y(), p.z()});
    }
  }
  const auto vec = [](const Eigen::Vector3d& v) { return nlohmann::json{v.x(), v.y(), v.z()}; };
  if (q.gravity_query) j["gravity_query"] = vec(*q.gravity_query);
  if (q.gravity_map) j["gravity_map"] = vec(*q.gravity_map);
  return j;
}

nlohmann::ordered_json LocalizeResultToJson(const MethodInfo& method, const LocalizeResult& r,
                                            bool with_inliers) {
  nlohmann::ordered_json j;
  const auto finite_or_null = [](double x) {
    return std::isfinite(x) ? nlohmann::ordered_json(x) : nlohmann::ordered_json(nullptr);
  };
  j["method"] = std::string(method.name);
  j["success"] = r.success;
  if (!r.success) j["reason"] = r.failure;
  if (r.has_pose) {
    const Eigen::Quaterniond& q = r.query_from_world.rotation;
    const Eigen::Vector3d& t = r.query_from_world.translation;
    // A rejected pose is reported under its own name, never as "q"/"t".
    const std::string prefix = r.success ? "" : "rejected_";
    j[prefix + "q"] = {q.w(), q.x(), q.y(), q.z()};
    j[prefix + "t"] = {t.x(), t.y(), t.z()};
    j[prefix + "scale"] = r.query_from_world.scale;
    const Eigen::Vector3d c = r.query_from_world.Inverse().translation;
    j[prefix + "center"] = {c.x(), c.y(), c.z()};
  }
  j["num_correspondences"] = r.num_correspondences;
  if (r.rejected_observations > 0) j["rejected_observations"] = r.rejected_observations;
  j["num_inliers"] = r.inliers.size();
  j["inlier_ratio"] = r.num_correspondences > 0
                          ? static_cast<double>(r.inliers.size()) / r.num_correspondences
                          : 0.0;
  if (r.has_pose) {
    j["uncertainty"] = {{"rotation_deg", finite_or_null(r.uncertainty.rotation_deg)},
                        {"position", finite_or_null(r.uncertainty.position)},
                        {"sigma_px", r.uncertainty.sigma_px}};
    if (r.inlier_distance > 0) j["uncertainty"]["distance_to_scene"] = r.inlier_distance;
    if (r.calibration_check) {  // the two shares of it
      j["uncertainty"]["from_matches"] = {
          {"rotation_deg", finite_or_null(r.matches_uncertainty.rotation_deg)},
          {"position", finite_or_null(r.matches_uncertainty.position)}};
      j["uncertainty"]["from_calibration"] = {
          {"rotation_deg", finite_or_null(r.calibration_check->rotation_deg)},
          {"position", finite_or_null(r.calibration_check->position)}};
    }
    if (r.local_scale) {
      j["uncertainty"]["scale_from"] = "local_points";
      j["uncertainty"]["sigma_local"] = r.local_scale->sigma_local;
      j["uncertainty"]["log_scale_se"] = r.local_scale->log_scale_se;
    }
  }
  j["stats"] = {{"iterations", r.stats.iterations},
                {"stop_reason", r.stats.stop_reason},
                {"sampling", r.stats.progressive ? "progressive" : "uniform"},
                {"uniform_iterations", r.stats.uniform_iterations},
                {"inlier_ratio", r.stats.inlier_ratio},
                {"mean_solutions", r.stats.mean_solutions},
                {"solver_us", r.stats.solver_us},
                {"ransac_ms", r.stats.ransac_ms},
                {"ransac_time_ms",
                 {{"solver", r.stats.solver_ms},
                  {"scoring", r.stats.scoring_ms},
                  {"local_optimization", r.stats.lo_ms}}},
                {"refine_ms", r.refine_ms},
                {"refine_iterations", r.refine_iterations},
                {"reprojection_px",
                 {{"initial", r.reprojection_initial_px}, {"refined", r.reprojection_refined_px}}}};
  if (r.refined_focal) j["refined_focal"] = *r.refined_focal;
  if (r.calibration_check) {
    const CalibrationCheck& c = *r.calibration_check;
    j["calibration_check"] = {
        {"given_focal", r.given_focal},
        {"best_fit_focal", c.best_fit_focal},
        {"interval", {c.interval[0], finite_or_null(c.interval[1])}},
        {"log_focal_se", finite_or_null(c.log_focal_se)},
        {"deviance", c.deviance},
        {"principal_point",
         {{"given", c.given_principal},
          {"best_fit", c.best_fit_principal},
          {"se_px", {finite_or_null(c.principal_se[0]), finite_or_null(c.principal_se[1])}},
          {"deviance", c.principal_deviance}}}};
    const auto extra = [&](const CalibrationCheck::Extra& e) {
      return nlohmann::ordered_json{
          {"best_fit_change", e.best}, {"se", finite_or_null(e.se)}, {"deviance", e.deviance}};
    };
    if (c.log_aspect.tested) j["calibration_check"]["log_aspect"] = extra(c.log_aspect);
    if (c.radial.tested) j["calibration_check"]["radial_k1"] = extra(c.radial);
    if (c.joint.fitted) {
      // The camera fitted as a whole: each fitted parameter's change and its
      // marginal standard error, the given camera's deviance and its limit.
      static constexpr std::array<const char*, kJointParameters> kNames = {
          "log_focal", "cx_px", "cy_px", "log_aspect", "radial_lambda", "p1", "p2"};
      nlohmann::ordered_json change, se;
      for (size_t k = 0; k < kNames.size(); ++k) {
        if (!c.joint.active[k]) continue;
        change[kNames[k]] = c.joint.theta[k];
        se[kNames[k]] = finite_or_null(c.joint.se[k]);
      }
      j["calibration_check"]["joint"] = {{"change", change},
                                         {"se", se},
                                         {"se_scale", c.joint.se_scale},
                                         {"pose_shift_deg", c.joint.pose_shift_deg},
                                         {"pose_shift_centre", c.joint.pose_shift_centre},
                                         {"deviance", c.joint.deviance},
                                         {"deviance_limit", c.joint.DevianceLimit()}};
    }
  }
  if (with_inliers) j["inliers"] = r.inliers;
  if (with_inliers && !r.camera_observations.empty()) {
    j["cameras"] = nlohmann::json::array();
    for (size_t c = 0; c < r.camera_observations.size(); ++c) {
      j["cameras"].push_back(
          {{"observations", r.camera_observations[c]}, {"inliers", r.camera_inliers[c]}});
    }
  }
  return j;
}

void AddPhotoStats(size_t num_features, size_t num_matches, double decode_ms, double extract_ms,
                   double match_ms, const LocalizeResult& result, nlohmann::ordered_json* j,
                   std::span<const ImageOrientation> orientations) {
  // Photos whose EXIF orientation turns them: whether the pixels were turned
  // (the camera fits the displayed size) or used as stored (it fits those).
  bool any = false;
  for (const ImageOrientation& o : orientations) any = any || o.exif != 1;
  if (any) {
    (*j)["orientation"] = nlohmann::json::array();
    for (const ImageOrientation& o : orientations) {
      (*j)["orientation"].push_back({{"exif", o.exif}, {"applied", o.applied}});
    }
  }
  (*j)["num_features"] = num_features;
  (*j)["num_matches"] = num_matches;
  (*j)["times_ms"] = {{"decode", decode_ms},
                      {"extract", extract_ms},
                      {"match", match_ms},
                      {"ransac", result.stats.ransac_ms},
                      {"refine", result.refine_ms}};
}

std::string LocalizeResultToColmapImagesTxt(const LocalizeResult& r, const std::string& name,
                                            uint32_t image_id, uint32_t camera_id) {
  if (!r.success) Fail("no pose to write in COLMAP's format: {}", r.failure);
  if (name.find_first_of(" \t\n") != std::string::npos) {
    Fail("image name '{}' has white space, which COLMAP's images.txt cannot hold", name);
  }
  const Eigen::Quaterniond& q = r.query_from_world.rotation;
  const Eigen::Vector3d& t = r.query_from_world.translation;
  return fmt::format(
      "# Image list with two lines of data per image:\n"
      "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
      "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
      "{} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {} {}\n\n",
      image_id, q.w(), q.x(), q.y(), q.z(), t.x(), t.y(), t.z(), camera_id, name);
}

}  // namespace linecloud
