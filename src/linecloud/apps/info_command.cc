#include <filesystem>
#include <iostream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "linecloud/apps/commands.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/io/line_cloud_info.h"
#include "linecloud/io/ply.h"
#include "linecloud/lifting/key.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

struct InfoArgs {
  std::string map;
  bool json = false;
};

void RunInfo(const InfoArgs& args) {
  if (args.map.empty()) Fail("give the map: linecloud info --map MAP.lcm");
  const LineCloud cloud = ReadLineCloud(args.map);  // the magic checked before the rest is read
  const uintmax_t file_bytes = std::filesystem::file_size(args.map);
  Eigen::Vector3d min, max;
  AnchorBoundingBox(cloud, &min, &max);
  const nlohmann::json j = LineCloudInfo(cloud, args.map, file_bytes);
  if (args.json) {
    std::cout << j.dump(2) << "\n";
    return;
  }
  std::cout << fmt::format(
      "{}\n"
      "  format            linecloud map, version {}\n"
      "  lines             {}\n"
      "  encoding          {}\n"
      "  descriptors       {}\n"
      "  key fingerprint   {}\n"
      "  gravity           {}\n"
      "  anchor bbox min   ({:.4f}, {:.4f}, {:.4f})\n"
      "  anchor bbox max   ({:.4f}, {:.4f}, {:.4f})\n"
      "  file size         {} bytes ({:.1f} bytes per line)\n",
      args.map, j["format_version"].get<int>(), cloud.size(), LineEncodingName(cloud.encoding),
      cloud.has_descriptors() ? fmt::format("yes: {}-D {} ({})", cloud.descriptor_dim,
                                            cloud.descriptor_type, cloud.descriptor_aggregation)
                              : std::string("no"),
      ToHex(cloud.key_fingerprint),
      cloud.gravity ? fmt::format("({:.4f}, {:.4f}, {:.4f})", cloud.gravity->x(),
                                  cloud.gravity->y(), cloud.gravity->z())
                    : std::string("unknown (lift --gravity x,y,z)"),
      min.x(), min.y(), min.z(), max.x(), max.y(), max.z(), file_bytes,
      j["bytes_per_line"].get<double>());
}

}  // namespace

void RegisterInfoCommand(CLI::App& app) {
  auto args = std::make_shared<InfoArgs>();
  CLI::App* cmd = app.add_subcommand("info", "Describe a line-cloud map (.lcm)");
  // --map like every other command; the positional form still works.
  auto* positional = cmd->add_option("map", args->map, "Line-cloud map (.lcm)");
  auto* flag = cmd->add_option("--map", args->map, "Line-cloud map (.lcm)");
  positional->excludes(flag);
  cmd->add_flag("--json", args->json, "Print JSON instead of text");
  cmd->callback([args] { RunInfo(*args); });
}

}  // namespace linecloud
