#include "linecloud/eval/eval_work.h"

#include "linecloud/io/json_util.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using nlohmann::json;

json Vec(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }

const json& Field(const json& j, const char* key, const std::string& where) {
  if (!j.is_object() || !j.contains(key)) Fail("{}: missing field '{}'", where, key);
  return j.at(key);
}

template <typename T>
T Get(const json& j, const char* key, const std::string& where) {
  const json& f = Field(j, key, where);
  try {
    return f.get<T>();
  } catch (const json::exception&) {
    Fail("{}.{}: wrong type", where, key);
  }
}

}  // namespace

PosedRig PoseRig(const EvalGroup& g, bool similarity) {
  PosedRig rig;
  rig.scale = similarity ? g.local_scale : 1.0;
  for (const EvalImage& im : g.images) {
    rig.cam_from_rig.push_back(im.cam_from_rig);
    rig.cam_from_rig.back().translation *= rig.scale;
  }
  rig.rig_from_world =
      Sim3d(rig.scale, g.rig_from_world.rotation, rig.scale * g.rig_from_world.translation);
  return rig;
}

json EvalWorkToJson(const EvalWork& w) {
  json j;
  j["format"] = "linecloud-eval-work";
  j["version"] = 1;
  j["dataset"] = w.dataset;
  j["dataset_dir"] = w.dataset_dir;
  j["units"] = w.units;
  j["gravity_world"] = Vec(w.gravity_world);
  j["gravity_source"] = w.gravity_source;
  j["gravity_noise_deg"] = w.gravity_noise_deg;
  j["reconstruction"] = w.reconstruction;
  json cams = json::array();
  for (const auto& [id, c] : w.cameras) {
    cams.push_back({{"id", id},
                    {"model", CameraModelName(c.model_id)},
                    {"width", c.width},
                    {"height", c.height},
                    {"params", c.params}});
  }
  j["cameras"] = cams;
  json groups = json::array();
  for (const EvalGroup& g : w.groups) {
    json jg = {
        {"name", g.name},
        {"map", g.map_dir},
        {"has_rig", g.has_rig},
        {"rig_source", g.rig_source},
        {"local_scale", g.local_scale},
        {"map_points", g.map_points},
        {"rig_from_world", PoseToJson(g.rig_from_world.rotation, g.rig_from_world.translation)},
        {"gravity_rig", Vec(g.gravity_rig)}};
    json images = json::array();
    for (const EvalImage& im : g.images) {
      json corr = json::array(), local = json::array();
      for (size_t k = 0; k < im.correspondences.size(); ++k) {
        const EvalCorrespondence& c = im.correspondences[k];
        corr.push_back(json::array({c.xy.x(), c.xy.y(), c.point_id, c.votes}));
        if (c.point_local) {
          local.push_back(
              json::array({k, c.point_local->x(), c.point_local->y(), c.point_local->z()}));
        }
      }
      images.push_back(
          {{"name", im.name},
           {"camera", im.camera_id},
           {"cam_from_world",
            PoseToJson(im.cam_from_world.rotation, im.cam_from_world.translation)},
           {"cam_from_rig", PoseToJson(im.cam_from_rig.rotation, im.cam_from_rig.translation)},
           {"gravity", Vec(im.gravity)},
           {"correspondences", corr},
           {"local_points", local}});
    }
    jg["images"] = images;
    groups.push_back(jg);
  }
  j["groups"] = groups;
  return j;
}

EvalWork EvalWorkFromJson(const json& j, const std::string& source) {
  if (!j.is_object() || j.value("format", "") != "linecloud-eval-work") {
    Fail("{}: not a linecloud eval work file (run `linecloud eval prepare`)", source);
  }
  if (j.value("version", 0) != 1) Fail("{}: unsupported version {}", source, j.value("version", 0));
  EvalWork w;
  w.dataset = Get<std::string>(j, "dataset", source);
  w.dataset_dir = Get<std::string>(j, "dataset_dir", source);
  w.units = Get<std::string>(j, "units", source);
  w.gravity_world = JsonVector3(Field(j, "gravity_world", source), source + ": gravity_world");
  w.gravity_source = Get<std::string>(j, "gravity_source", source);
  w.gravity_noise_deg = Get<double>(j, "gravity_noise_deg", source);
  w.reconstruction = j.value("reconstruction", json::object());
  const json& cams = Field(j, "cameras", source);
  for (size_t i = 0; i < cams.size(); ++i) {
    const std::string where = fmt::format("{}: cameras[{}]", source, i);
    Camera c;
    c.camera_id = Get<uint32_t>(cams[i], "id", where);
    c.model_id = CameraModelFromName(Get<std::string>(cams[i], "model", where));
    c.width = Get<uint64_t>(cams[i], "width", where);
    c.height = Get<uint64_t>(cams[i], "height", where);
    c.params = Get<std::vector<double>>(cams[i], "params", where);
    c.Check(where);
    w.cameras[c.camera_id] = c;
  }
  const json& groups = Field(j, "groups", source);
  for (size_t gi = 0; gi < groups.size(); ++gi) {
    const json& jg = groups[gi];
    const std::string where = fmt::format("{}: groups[{}]", source, gi);
    EvalGroup g;
    g.name = Get<std::string>(jg, "name", where);
    g.map_dir = Get<std::string>(jg, "map", where);
    g.has_rig = Get<bool>(jg, "has_rig", where);
    g.rig_source = Get<std::string>(jg, "rig_source", where);
    g.local_scale = Get<double>(jg, "local_scale", where);
    g.map_points = Get<int>(jg, "map_points", where);
    g.rig_from_world = JsonPose(Field(jg, "rig_from_world", where), where + ".rig_from_world");
    g.gravity_rig = JsonVector3(Field(jg, "gravity_rig", where), where + ".gravity_rig");
    const json& images = Field(jg, "images", where);
    for (size_t ii = 0; ii < images.size(); ++ii) {
      const json& ji = images[ii];
      const std::string wi = fmt::format("{}.images[{}]", where, ii);
      EvalImage im;
      im.name = Get<std::string>(ji, "name", wi);
      im.camera_id = Get<uint32_t>(ji, "camera", wi);
      if (!w.cameras.count(im.camera_id)) Fail("{}.camera: unknown camera {}", wi, im.camera_id);
      im.cam_from_world = JsonPose(Field(ji, "cam_from_world", wi), wi + ".cam_from_world");
      im.cam_from_rig = JsonPose(Field(ji, "cam_from_rig", wi), wi + ".cam_from_rig");
      im.gravity = JsonVector3(Field(ji, "gravity", wi), wi + ".gravity");
      const json& corr = Field(ji, "correspondences", wi);
      for (size_t k = 0; k < corr.size(); ++k) {
        if (!corr[k].is_array() || corr[k].size() != 4)
          Fail("{}.correspondences[{}]: expected [x, y, id, votes]", wi, k);
        EvalCorrespondence c;
        try {
          c.xy = {corr[k][0].get<double>(), corr[k][1].get<double>()};
          c.point_id = corr[k][2].get<uint64_t>();
          c.votes = corr[k][3].get<int>();
        } catch (const json::exception&) {
          Fail("{}.correspondences[{}]: expected [x, y, id, votes]", wi, k);
        }
        if (!c.xy.allFinite()) Fail("{}.correspondences[{}]: non-finite pixel", wi, k);
        im.correspondences.push_back(c);
      }
      const json& local = Field(ji, "local_points", wi);
      for (size_t k = 0; k < local.size(); ++k) {
        const std::string wl = fmt::format("{}.local_points[{}]", wi, k);
        if (!local[k].is_array() || local[k].size() != 4) Fail("{}: expected [index, x, y, z]", wl);
        size_t idx = 0;
        Eigen::Vector3d X;
        try {
          idx = local[k][0].get<size_t>();
          X = {local[k][1].get<double>(), local[k][2].get<double>(), local[k][3].get<double>()};
        } catch (const json::exception&) {
          Fail("{}: expected [index, x, y, z]", wl);
        }
        if (idx >= im.correspondences.size()) Fail("{}: index {} out of range", wl, idx);
        if (!X.allFinite()) Fail("{}: non-finite point", wl);
        im.correspondences[idx].point_local = X;
      }
      g.images.push_back(std::move(im));
    }
    w.groups.push_back(std::move(g));
  }
  return w;
}

}  // namespace linecloud
