#include <iostream>

#include <nlohmann/json.hpp>

#include "linecloud/apps/commands.h"
#include "linecloud/io/json_util.h"
#include "linecloud/io/problem_json.h"
#include "linecloud/solvers/minimal_problem.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

void RunSolve(const std::string& path) {
  const MinimalProblem problem = ParseProblemJson(ReadJsonFile(path), path);
  const MethodInfo& method = *problem.method;
  const MinimalSample& s = problem.sample;
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
  CLI::App* cmd =
      app.add_subcommand("solve",
                         "Run one minimal solver on one minimal sample (PROBLEM.json) and print "
                         "every solution");
  cmd->add_option("problem", *path, "Problem file (docs/formats.md, PROBLEM.json)")->required();
  cmd->callback([path] { RunSolve(*path); });
}

}  // namespace linecloud
