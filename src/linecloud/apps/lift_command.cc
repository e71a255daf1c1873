#include <chrono>
#include <iostream>

#include <fmt/format.h>

#include "linecloud/apps/commands.h"
#include "linecloud/io/colmap_database.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/io/track_descriptors.h"
#include "linecloud/lifting/lifting.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

struct LiftArgs {
  std::string model, out, key_file, database, descriptor = "medoid";
  bool compact = false;
  bool force = false;
};

// Refuses to replace a map lifted with another key: the old and new lines of
// each point would intersect in the point.
void CheckExistingOutput(const LiftArgs& args, const LiftingKey& key) {
  if (!FileExists(args.out) || args.force) return;
  LineCloud existing;
  try {
    existing = ReadLineCloud(args.out);
  } catch (const Error&) {
    Fail("{}: exists and is not a readable line cloud; remove it or pass "
         "--force",
         args.out);
  }
  if (existing.key_fingerprint != key.Fingerprint()) {
    Fail("{}: was lifted with another key (fingerprint {}); lifting one map "
         "with two keys reveals its points by intersecting the lines. Lift "
         "with that map's key, or pass --force if the old file was never "
         "shared",
         args.out, ToHex(existing.key_fingerprint));
  }
}

void RunLift(const LiftArgs& args) {
  const auto start = std::chrono::steady_clock::now();
  const Reconstruction rec = ReadColmapModel(args.model);
  const std::vector<uint64_t> ids = rec.SortedPoint3DIds();
  if (ids.empty()) Fail("{}: the model has no 3D points to lift", args.model);

  PointDescriptors descriptors;
  DescriptorAggregation aggregation = DescriptorAggregationFromName(args.descriptor);
  if (!args.database.empty()) {
    const ColmapDatabase db(args.database);
    descriptors = ComputePointDescriptors(rec, ids, db, aggregation);
  }

  // The key: given, next to the output from an earlier run, or new.
  std::string key_path = args.key_file;
  bool created_key = false;
  if (key_path.empty()) {
    key_path = args.out + ".key";
    if (FileExists(key_path)) {
      std::cerr << fmt::format("reusing the lifting key {}\n", key_path);
    } else {
      WriteKeyFile(key_path, LiftingKey::Generate());
      created_key = true;
    }
  }
  try {
    const LiftingKey key = ReadKeyFile(key_path);
    CheckExistingOutput(args, key);

    std::vector<Eigen::Vector3d> points;
    points.reserve(ids.size());
    for (const uint64_t id : ids) points.push_back(rec.points3D.at(id).xyz);
    LiftingOptions options;
    options.encoding = args.compact ? LineEncoding::kCompact : LineEncoding::kPlucker;
    LineCloud cloud = LiftPoints(ids, points, key, options);
    if (descriptors.dim > 0) {
      cloud.descriptor_dim = descriptors.dim;
      cloud.descriptors = std::move(descriptors.data);
      cloud.descriptor_type = "colmap-sift-uint8";
      cloud.descriptor_aggregation = DescriptorAggregationName(aggregation);
    }
    WriteLineCloud(cloud, args.out);
    const double seconds = std::chrono::duration<double>(
                               std::chrono::steady_clock::now() - start)
                               .count();
    std::cout << fmt::format(
        "lifted {} points of {} to {} lines ({}{}) in {:.2f} s -> {}\n",
        ids.size(), args.model, cloud.size(), LineEncodingName(cloud.encoding),
        cloud.has_descriptors()
            ? fmt::format(", {}-D descriptors ({})", cloud.descriptor_dim,
                          cloud.descriptor_aggregation)
            : "",
        seconds, args.out);
    if (created_key) {
      std::cout << fmt::format(
          "created a new lifting key {} (owner-only). Keep it secret and pass "
          "it with --key-file whenever you lift this map again: two different "
          "liftings of one map reveal its points.\n",
          key_path);
    }
  } catch (...) {
    if (created_key) std::remove(key_path.c_str());
    throw;
  }
}

}  // namespace

void RegisterLiftCommand(CLI::App& app) {
  auto args = std::make_shared<LiftArgs>();
  CLI::App* cmd = app.add_subcommand(
      "lift", "Lift a COLMAP model's points to a line cloud (.lcm)");
  cmd->add_option("--model", args->model, "COLMAP sparse model folder (bin or txt)")
      ->required();
  cmd->add_option("--out", args->out, "Output line-cloud map (.lcm)")->required();
  cmd->add_option("--key-file", args->key_file,
                  "Secret lifting key of this map (default: OUT.key, created "
                  "if missing)");
  cmd->add_option("--database", args->database,
                  "COLMAP database: attach one descriptor per line");
  cmd->add_option("--descriptor", args->descriptor,
                  "How a track's descriptors become one: medoid or mean")
      ->check(CLI::IsMember({"medoid", "mean"}));
  cmd->add_flag("--compact", args->compact,
                "The paper's compact encoding (9 bytes per line)");
  cmd->add_flag("--force", args->force,
                "Overwrite OUT even if another key lifted it");
  cmd->callback([args] { RunLift(*args); });
}

}  // namespace linecloud
