#include <iostream>

#include <nlohmann/json.hpp>

#include "linecloud/apps/commands.h"
#include "linecloud/io/json_util.h"
#include "linecloud/solvers/minimal_problem.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

void RunSolve(const std::string& path) {
  const nlohmann::json j = ReadJsonFile(path);
  if (!j.is_object()) Fail("{}: expected a JSON object", path);
  if (!j.contains("method") || !j["method"].is_string()) {
    Fail("{}: field 'method' (string) is missing", path);
  }
  const MethodInfo& method = FindMethod(j["method"].get<std::string>());
  MinimalSample s;
  const auto field = [&](const char* name) { return path + ": " + name; };
  if (j.contains("bearings")) s.bearings = JsonVector3List(j["bearings"], field("bearings"));
  if (j.contains("points")) s.points = JsonVector3List(j["points"], field("points"));
  if (j.contains("points_local")) {
    s.points_local = JsonVector3List(j["points_local"], field("points_local"));
  }
  if (j.contains("lines")) s.lines = JsonLineList(j["lines"], field("lines"));
  if (j.contains("camera_index")) {
    const auto& ci = j["camera_index"];
    if (!ci.is_array()) Fail("{}: expected an array of integers", field("camera_index"));
    for (size_t i = 0; i < ci.size(); ++i) {
      if (!ci[i].is_number_integer()) {
        Fail("{}[{}]: expected an integer", field("camera_index"), i);
      }
      s.camera_index.push_back(ci[i].get<int>());
    }
  }
  if (j.contains("cam_from_rig")) {
    const auto& cr = j["cam_from_rig"];
    if (!cr.is_array()) Fail("{}: expected an array of poses", field("cam_from_rig"));
    for (size_t i = 0; i < cr.size(); ++i) {
      s.cam_from_rig.push_back(
          JsonPose(cr[i], field("cam_from_rig") + "[" + std::to_string(i) + "]"));
    }
  }
  // Bearings need only be directions: normalise them.
  for (Eigen::Vector3d& b : s.bearings) {
    if (b.norm() > 0) b.normalize();
  }
  CheckSample(method, s, path);
  std::vector<Sim3d> solutions;
  SolveMinimal(method, s, &solutions);
  nlohmann::json out;
  out["method"] = std::string(method.name);
  out["solutions"] = nlohmann::json::array();
  for (const Sim3d& p : solutions) {
    nlohmann::json sj = PoseToJson(p.rotation, p.translation);
    sj["scale"] = p.scale;
    out["solutions"].push_back(sj);
  }
  std::cout << out.dump(2) << "\n";
}

}  // namespace

void RegisterSolveCommand(CLI::App& app) {
  auto path = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "solve", "Run one minimal solver on one minimal sample (PROBLEM.json) and print "
               "every solution");
  cmd->add_option("problem", *path, "Problem file (see SPEC.md)")->required();
  cmd->callback([path] { RunSolve(*path); });
}

}  // namespace linecloud
