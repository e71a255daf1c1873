#include <iostream>

#include <fmt/format.h>

#include "linecloud/apps/commands.h"
#include "linecloud/util/file.h"
#include "linecloud/io/lift_model.h"
#include "linecloud/lifting/key.h"
#include "linecloud/pipeline/image_query.h"
#include "linecloud/privacy/map_lifting.h"

namespace linecloud {
namespace {

struct LiftArgs {
  LiftModelOptions options;
  std::string descriptor = "medoid";
  std::string gravity;
  std::string sparsify_mode = "uniform";
  double resist_attack = -1;  // < 0: off
  bool quiet = false;
};

void RunLift(LiftArgs args) {
  RefuseOutputOverInputs(args.options.out_path,
                         {args.options.model_dir, args.options.database, args.options.key_file},
                         "--out");
  args.options.aggregation = DescriptorAggregationFromName(args.descriptor);
  // One description of a lifting, as `eval` takes it (privacy/map_lifting.h).
  MapLifting lifting;
  lifting.sparsify = args.options.sparsify;
  lifting.sparsify_mode = SparsifyModeFromName(args.sparsify_mode, "--sparsify-mode");
  lifting.resist_attack = args.resist_attack;
  lifting.compact = args.options.compact;
  if (!args.gravity.empty()) args.options.gravity = ParseDirection(args.gravity, "--gravity");
  const LiftModelResult r =
      LiftModelWith(args.options, lifting, [quiet = args.quiet](size_t round, double recovered) {
        if (!quiet) {
          std::cerr << fmt::format(
              "resist: round {}: the attack recovers {:.1f} % of the points kept\n", round,
              100 * recovered);
        }
      });
  const LineCloud& cloud = r.cloud;
  std::cout << fmt::format(
      "lifted {} points of {} to {} lines ({}{}) in {:.2f} s -> {}\n", r.num_points,
      args.options.model_dir, cloud.size(), LineEncodingName(cloud.encoding),
      cloud.has_descriptors() ? fmt::format(", {}-D descriptors ({})", cloud.descriptor_dim,
                                            cloud.descriptor_aggregation)
                              : "",
      r.seconds, args.options.out_path);
  std::cout << fmt::format("key: {} ({}), fingerprint {}\n", r.key_path, r.key_source,
                           ToHex(cloud.key_fingerprint));
  const IdentityResult& id = r.identity;
  std::cout << fmt::format(
      "identity: {} points keep a released line (observations; {} of them its very line), {} "
      "share a place with another point, {} lie on a released line, {} are new{}{}\n",
      id.from_observations, id.on_released_line, id.from_same_place, id.from_released_place,
      id.fresh,
      id.left_out ? fmt::format(", {} left out (they merge points released with different lines)",
                                id.left_out)
                  : "",
      id.shared_images ? fmt::format("; aligned with the released version through {} images "
                                     "(points {:.2g} % of the diagonal from their lines)",
                                     id.shared_images, 100 * id.misalignment)
                       : "");
  if (r.key_source.starts_with("new")) {
    std::cout << "This key now belongs to the model: every later lift of it (any output, "
                 "encoding or option) reuses it. Keep it secret and never delete it: two "
                 "different liftings of one model reveal its points.\n";
  }
}

}  // namespace

void RegisterLiftCommand(CLI::App& app) {
  auto args = std::make_shared<LiftArgs>();
  LiftModelOptions& o = args->options;
  CLI::App* cmd = app.add_subcommand(
      "lift", "Lift a COLMAP model's points to a line cloud (.lcm) under the model's one key");
  cmd->add_option("--model", o.model_dir, "COLMAP sparse model folder (bin or txt)")->required();
  cmd->add_option("--out", o.out_path, "Output line-cloud map (.lcm)")->required();
  cmd->add_option("--key-file", o.key_file,
                  "Secret lifting key of this model (created there, mode 0600, if missing; "
                  "default: the model's key in the key store)");
  cmd->add_option("--key-store", o.key_store,
                  "Per-user key store (default: $LINECLOUD_KEY_STORE, "
                  "$XDG_DATA_HOME/linecloud/keys or ~/.local/share/linecloud/keys)");
  cmd->add_option("--database", o.database, "COLMAP database: attach one descriptor per line");
  cmd->add_option("--descriptor", args->descriptor,
                  "How a track's descriptors become one: medoid or mean")
      ->check(CLI::IsMember({"medoid", "mean"}));
  cmd->add_flag("--compact", o.compact,
                "The paper's compact encoding (9 bytes per line); a model's first lift with "
                "--compact gives it a key of the 256 compact directions");
  cmd->add_flag("--force", o.force,
                "Replace OUT even if another key or other lines lifted it, and lift with a key "
                "other than the model's (only for files never shared)");
  cmd->add_option("--gravity", args->gravity,
                  "The model frame's gravity direction x,y,z (stored with the map, for the +u "
                  "methods)");
  cmd->add_option("--sparsify", o.sparsify,
                  "Drop this share of the points (keyed, reproducible; the kept points get the "
                  "same lines as in the full map)")
      ->capture_default_str();
  cmd->add_option("--sparsify-mode", args->sparsify_mode,
                  "uniform (each point alike) or balanced (cap the local density: at most one "
                  "point per cell of a keyed grid)")
      ->check(CLI::IsMember({"uniform", "balanced"}))
      ->capture_default_str();
  cmd->add_option("--resist-attack", args->resist_attack,
                  "Attack-aware sparsification: drop the points the density attack recovers "
                  "(within 1 % of the diagonal), re-attack, until at most this share is recovered")
      ->check(CLI::Range(0.0, 0.99));
  cmd->add_option("--same-place", o.identity.same_place,
                  "points closer than this share of the scene diagonal count as one place: they "
                  "get parallel lines, within this map and against the lines released before")
      ->capture_default_str();
  cmd->add_flag("--quiet", args->quiet, "no progress on standard error");
  cmd->add_flag("--allow-shared-key", o.allow_shared_key,
                "Accept a key file that other users can read");
  cmd->callback([args] { RunLift(*args); });
}

}  // namespace linecloud
