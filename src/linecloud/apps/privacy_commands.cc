#include <filesystem>
#include <iostream>

#include <fmt/format.h>

#include "linecloud/apps/commands.h"
#include "linecloud/apps/option_flags.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/io/ply.h"
#include "linecloud/privacy/attack_option_table.h"
#include "linecloud/privacy/audit.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

struct AttackArgs {
  std::string map_path, out_path;
  DensityAttackOptions attack;
  OptionFlags<OptionField<DensityAttackOptions>>
      flags;  // the attack's options (attack_option_table.h)
  bool quiet = false;
};

void SetProgress(DensityAttackOptions& o, bool quiet) {
  if (quiet) return;
  o.progress = [](const std::string& stage, size_t done, size_t total) {
    std::cerr << fmt::format("attack: {} {:.0f} % ({}/{} lines)\n", stage, 100.0 * done / total,
                             done, total);
  };
}

void RunAttack(AttackArgs args) {
  args.flags.Apply(&args.attack);
  RefuseOutputOverInputs(args.out_path, {args.map_path}, "--out");
  SetProgress(args.attack, args.quiet);
  const LineCloud cloud = ReadLineCloud(args.map_path);
  const DensityAttackResult r = RunDensityAttack(cloud, args.attack);
  WritePointsPly(args.out_path, r.points, {},
                 "linecloud attack: points recovered from a line cloud by its density "
                 "(Chelani, Kahl, Sattler, CVPR 2021)");
  std::cout << fmt::format(
      "recovered {} points from {} lines ({} nearest lines, {} refinement rounds, {} lines "
      "without votes) in {:.1f} s -> {}\n",
      r.points.size(), cloud.size(), r.line_neighbours, args.attack.refine_rounds,
      r.lines_without_votes, r.seconds, args.out_path);
}

void RunAuditCommand(AuditOptions options, bool quiet) {
  SetProgress(options.attack, quiet);
  if (!options.out_dir.empty()) {
    RefuseOutputOverInputs(options.out_dir,
                           {options.map_path, options.other_map_path, options.model_dir}, "--out");
  }
  std::cout << ToJson(RunAudit(options)).dump(2) << "\n";
}

}  // namespace

void RegisterAttackCommand(CLI::App& app) {
  auto args = std::make_shared<AttackArgs>();
  CLI::App* cmd = app.add_subcommand(
      "attack",
      "The attacker's view: recover points from a line cloud by its density (Chelani et al., "
      "CVPR 2021)");
  cmd->add_option("--map", args->map_path, "line-cloud map (.lcm)")->required();
  cmd->add_option("--out", args->out_path, "recovered points (.ply)")->required();
  args->flags.Add(cmd, AttackOptionTable());
  cmd->add_flag("--quiet", args->quiet, "no progress on standard error");
  cmd->callback([args] { RunAttack(*args); });
}

void RegisterAuditCommand(CLI::App& app) {
  auto options = std::make_shared<AuditOptions>();
  auto quiet = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(
      "audit",
      "The owner's view: run the published attacks on a map and score them against the secret "
      "model (report.json, report.md, recovered.ply, audit.png)");
  cmd->add_option("--map", options->map_path, "line-cloud map (.lcm)")->required();
  cmd->add_option("--model", options->model_dir, "the secret COLMAP model the map was lifted from")
      ->required();
  cmd->add_option("--other", options->other_map_path,
                  "another lifting or version of the model (e.g. re-triangulated, renumbered): "
                  "its lines paired with the map's by equal id, nearest descriptor and crossing, "
                  "then intersected");
  cmd->add_option("--out", options->out_dir, "output folder");
  cmd->add_option("--key-file", options->key_file, "the model's key (default: the key store's)");
  cmd->add_option("--key-store", options->key_store, "per-user key store");
  auto flags = std::make_shared<OptionFlags<OptionField<AuditOptions>>>();
  flags->Add(cmd, AuditOptionTable());
  cmd->add_flag("--quiet", *quiet, "no progress on standard error");
  cmd->callback([options, quiet, flags] {
    AuditOptions o = *options;
    flags->Apply(&o);
    RunAuditCommand(o, *quiet);
  });
}

}  // namespace linecloud
