#include <iostream>
#include <memory>

#include "linecloud/apps/commands.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/localize/localize.h"
#include "linecloud/localize/query_json.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

struct LocalizeArgs {
  std::string map_path;
  std::string model_dir;
  std::string query_path;
  std::string method;
  bool no_refine = false;
  double threshold = 4.0;
  uint64_t seed = 0;
  std::string out;
};

void RunLocalize(const LocalizeArgs& args) {
  const MethodInfo& method = FindMethod(args.method);
  if (args.map_path.empty() == args.model_dir.empty()) {
    Fail("give exactly one of --map MAP.lcm (line cloud) or --model DIR (point model)");
  }
  const Query query = ReadQueryJson(args.query_path);
  const LocalizationMap map = args.map_path.empty()
                                  ? LocalizationMap(PointMapFromModel(ReadColmapModel(args.model_dir)))
                                  : LocalizationMap(LineMapFromCloud(ReadLineCloud(args.map_path)));
  LocalizeOptions options;
  options.ransac.max_error = args.threshold;
  options.ransac.seed = args.seed;
  options.refine = !args.no_refine;
  const LocalizeResult result = Localize(method, query, map, options, args.query_path);
  const std::string text = LocalizeResultToJson(method, result).dump(2) + "\n";
  if (args.out.empty()) {
    std::cout << text;
  } else {
    WriteFileAtomically(args.out, [&](std::ostream& os) { os << text; });
  }
}

}  // namespace

void RegisterLocalizeCommand(CLI::App& app) {
  auto args = std::make_shared<LocalizeArgs>();
  CLI::App* cmd = app.add_subcommand(
      "localize", "Localize a query (QUERY.json) against a line cloud or a point model: RANSAC "
                  "with the method's minimal solver, then LM refinement");
  auto* map = cmd->add_option("--map", args->map_path, "Line cloud (.lcm)");
  auto* model = cmd->add_option("--model", args->model_dir, "COLMAP sparse model folder");
  map->excludes(model);
  cmd->add_option("--query", args->query_path, "Query file (SPEC.md)")->required();
  cmd->add_option("--method", args->method, "One of the 16 methods, e.g. p6L, p3P, m-P3P+l")
      ->required();
  cmd->add_flag("--no-refine", args->no_refine, "Skip the final LM refinement");
  cmd->add_option("--threshold", args->threshold, "RANSAC inlier threshold in pixels")
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "RANSAC seed")->capture_default_str();
  cmd->add_option("--out", args->out, "Write the result JSON here instead of stdout");
  cmd->callback([args] { RunLocalize(*args); });
}

}  // namespace linecloud
