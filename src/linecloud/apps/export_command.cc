#include <iostream>

#include <fmt/format.h>

#include "linecloud/apps/commands.h"
#include "linecloud/util/file.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/io/ply.h"

namespace linecloud {
namespace {

struct ExportArgs {
  std::string map, model, ply;
  double segment_length = 0;
};

void RunExport(const ExportArgs& args) {
  RefuseOutputOverInputs(args.ply, {args.map, args.model}, "--ply");
  if (!args.map.empty()) {
    const LineCloud cloud = ReadLineCloud(args.map);
    WriteLineCloudPly(cloud, args.ply, args.segment_length);
    std::cout << fmt::format("wrote {} line segments to {}\n", cloud.size(), args.ply);
  } else {
    const Reconstruction rec = ReadColmapModel(args.model);
    WriteModelPly(rec, args.ply);
    std::cout << fmt::format("wrote {} points to {}\n", rec.points3D.size(), args.ply);
  }
}

}  // namespace

void RegisterExportCommand(CLI::App& app) {
  auto args = std::make_shared<ExportArgs>();
  CLI::App* cmd =
      app.add_subcommand("export", "Export a line cloud (segments) or a point model to PLY");
  auto* map = cmd->add_option("--map", args->map, "Line-cloud map (.lcm)");
  auto* model = cmd->add_option("--model", args->model, "COLMAP model folder");
  map->excludes(model);
  cmd->add_option("--ply", args->ply, "Output PLY file")->required();
  cmd->add_option("--segment-length", args->segment_length,
                  "Length of each line segment (default: 5% of the anchors' "
                  "bounding-box diagonal)")
      ->check(CLI::NonNegativeNumber);
  cmd->callback([args, map, model] {
    if (map->count() + model->count() != 1) {
      throw CLI::ValidationError("export", "give exactly one of --map or --model");
    }
    RunExport(*args);
  });
}

}  // namespace linecloud
