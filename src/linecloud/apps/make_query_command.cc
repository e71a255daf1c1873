#include <iostream>

#include <fmt/format.h>

#include "linecloud/apps/commands.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/io/json_util.h"
#include "linecloud/io/lift_model.h"
#include "linecloud/localize/query_from_model.h"
#include "linecloud/localize/query_json.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

struct MakeQueryArgs {
  std::string model, image, out, key_file, key_store;
  bool points_only = false;
};

void RunMakeQuery(const MakeQueryArgs& args) {
  RefuseOutputOverInputs(args.out, {args.model, args.key_file}, "--out");
  const Reconstruction model = ReadColmapModel(args.model);
  std::optional<LiftingKey> key;
  if (!args.points_only) key = ModelKey(model, args.model, args.key_file, args.key_store);
  const ModelQuery q = QueryFromModelImage(model, args.model, args.image, key ? &*key : nullptr);
  nlohmann::json j = QueryToJson(q.query);
  j["image"] = args.image;
  j["reference"] = {
      {"cam_from_world", PoseToJson(q.cam_from_world.rotation, q.cam_from_world.translation)}};
  const std::string text = j.dump(1) + "\n";
  WriteFileAtomically(args.out, [&](std::ostream& os) { os << text; });
  std::cout << fmt::format("{} correspondences of {} -> {}{}\n", q.query.observations.size(),
                           args.image, args.out,
                           key ? " (point ids and the map's line ids)" : " (point ids)");
}

}  // namespace

void RegisterMakeQueryCommand(CLI::App& app) {
  auto args = std::make_shared<MakeQueryArgs>();
  CLI::App* cmd = app.add_subcommand(
      "make-query",
      "Write a QUERY.json from an image registered in a COLMAP model (its 2D-3D matches; line "
      "ids through the model's key), to try localize on your own data");
  cmd->add_option("--model", args->model, "COLMAP sparse model folder")->required();
  cmd->add_option("--image", args->image, "Image name as in the model (images.txt)")->required();
  cmd->add_option("--out", args->out, "Output QUERY.json")->required();
  cmd->add_option("--key-file", args->key_file, "The model's lifting key (default: key store)");
  cmd->add_option("--key-store", args->key_store, "Key store (default as for lift)");
  cmd->add_flag("--points-only", args->points_only, "Point ids only (for --model); needs no key");
  cmd->callback([args] { RunMakeQuery(*args); });
}

}  // namespace linecloud
