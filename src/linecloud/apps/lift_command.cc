#include <iostream>

#include <fmt/format.h>

#include "linecloud/apps/commands.h"
#include "linecloud/apps/option_flags.h"
#include "linecloud/util/file.h"
#include "linecloud/io/lift_model.h"
#include "linecloud/lifting/key.h"
#include "linecloud/pipeline/image_query.h"
#include "linecloud/privacy/lift_option_table.h"
#include "linecloud/privacy/map_lifting.h"

namespace linecloud {
namespace {

struct LiftArgs {
  LiftSettings settings;  // the paths here, the rest from the flags
  OptionFlags<OptionField<LiftSettings>> flags;
  bool quiet = false;
};

// Where each point's direction came from: parts that add up to the whole.
std::string IdentityLine(const IdentityResult& id, size_t points) {
  const size_t kept = id.from_observations + id.from_released_place;
  std::string line = fmt::format(
      "identity (one line per physical point across releases): of {} points, {} keep a "
      "released line ({} through their observations, {} found at their place{}; {} of the {} "
      "are the released line itself, the others parallel to it), {} share the direction of a "
      "point of this version within --same-place, {} get a new line",
      points, kept, id.from_observations, id.from_released_place,
      id.from_released_place
          ? fmt::format(": {} by their descriptor, {} the nearest", id.released_place_by_sketch,
                        id.from_released_place - id.released_place_by_sketch)
          : "",
      id.on_released_line, kept, id.from_same_place, id.fresh);
  if (id.left_out) {
    line +=
        fmt::format(", {} left out (they merge points released with different lines)", id.left_out);
  }
  if (id.shared_images) {
    line += fmt::format("; aligned with the released version through {} images", id.shared_images);
    if (id.from_observations >= 10) {
      line += fmt::format(" (points {:.2g} % of the diagonal from their lines, median)",
                          100 * id.misalignment);
    } else {
      line += fmt::format(
          " (checked: {} points lie within a tenth of --same-place of a released line, {} "
          "would by chance)",
          id.released_place_close, id.released_place_close_by_chance);
    }
  }
  return line;
}

void RunLift(LiftArgs args) {
  args.flags.Apply(&args.settings);
  const LiftModelOptions& o = args.settings.options;
  RefuseOutputOverInputs(o.out_path, {o.model_dir, o.database, o.key_file}, "--out");
  const LiftModelResult r =
      LiftModelWith(o, args.settings.lifting, [quiet = args.quiet](size_t round, double recovered) {
        if (!quiet) {
          std::cerr << fmt::format(
              "resist: round {}: the attack recovers {:.1f} % of the points kept\n", round,
              100 * recovered);
        }
      });
  const LineCloud& cloud = r.cloud;
  std::cout << fmt::format(
      "lifted {} points of {} to {} lines ({}{}) in {:.2f} s -> {}\n", r.num_points, o.model_dir,
      cloud.size(), LineEncodingName(cloud.encoding),
      cloud.has_descriptors() ? fmt::format(", {}-D descriptors ({})", cloud.descriptor_dim,
                                            cloud.descriptor_aggregation)
                              : "",
      r.seconds, o.out_path);
  const bool new_key = r.key_source.starts_with("new");
  if (args.quiet) {  // [newcomer] one line, and the new key's warning in one more
    if (new_key) {
      std::cout << fmt::format(
          "new key {}: keep it secret and never delete it; if this model was lifted before "
          "with another key store, use that key instead (--key-file)\n",
          r.key_path);
    }
    return;
  }
  std::cout << fmt::format("key: {} ({}), fingerprint {}; its ledger in the key store {}\n",
                           r.key_path, r.key_source, ToHex(cloud.key_fingerprint), r.key_store);
  std::cout << IdentityLine(r.identity, r.num_points) << "\n";
  if (new_key) {
    std::cout << "This key now belongs to the model: every later lift of it (any output, "
                 "encoding or option) reuses it. Keep it secret and never delete it: two "
                 "different liftings of one model reveal its points. If this model (or another "
                 "map of the same place) was already lifted and released from another key store "
                 "or machine, the two releases together reveal its points: delete this output, "
                 "and lift with that key (--key-file KEY, or --key-store / LINECLOUD_KEY_STORE "
                 "naming that store).\n";
  }
}

}  // namespace

void RegisterLiftCommand(CLI::App& app) {
  auto args = std::make_shared<LiftArgs>();
  LiftModelOptions& o = args->settings.options;
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
  args->flags.Add(cmd, LiftOptionTable());
  cmd->add_flag("--quiet", args->quiet,
                "no progress; one line out (two for a new key: keep it secret)");
  cmd->callback([args] { RunLift(*args); });
}

}  // namespace linecloud
