// `linecloud audit`: the owner of a map measures what an attacker recovers
// from it. The map's lines are tied to the secret model's points through the
// model's key (line id → point id), the published attacks are run on the map
// as an attacker would (density_attack.h; two_key_attack.h with a second map),
// and the recovered points are scored against the secret ones.
//
// Outputs in `out_dir` (when set): report.json, report.md, recovered.ply
// (the recovered points coloured by error) and audit.png (audit_figure.h).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include "linecloud/io/colmap_model.h"
#include "linecloud/lifting/key.h"
#include "linecloud/lifting/line_cloud.h"
#include "linecloud/privacy/audit_report.h"
#include "linecloud/privacy/density_attack.h"

namespace linecloud {

struct AuditOptions {
  std::string map_path;
  std::string model_dir;       // the secret model the map was lifted from
  std::string other_map_path;  // a second lifting of the model: the two-key attack
  std::string out_dir;         // empty: report on stdout only
  std::string key_file;        // empty: the key store's key of the model
  std::string key_store;
  double metric_scale = 0;  // metres per model unit; 0: not metric
  bool skip_density_attack = false;
  // The pairing attacks (two versions; one map's own lines): lines passing
  // within crossing_tolerance × the scene diagonal of each other are
  // intersected; a point counts as recovered when an intersection lies within
  // recovered_within × the diagonal of it.
  double crossing_tolerance = 1e-3;
  double recovered_within = 1e-4;
  DensityAttackOptions attack;

  void Check() const;  // throws Error naming the option
};

// The model's point behind each line of `cloud` (in its order). Throws Error
// when the map was lifted with another key or from another model.
std::vector<Eigen::Vector3d> SecretPointsOfLines(const LineCloud& cloud,
                                                 const Reconstruction& model, const LiftingKey& key,
                                                 const std::string& map_name);

// Runs the audit, writes the outputs, returns the report (report.json is its ToJson).
AuditReport RunAudit(const AuditOptions& options);
// The same on a map already read; `options.map_path` names it in the report.
AuditReport RunAudit(const LineCloud& cloud, const AuditOptions& options);

}  // namespace linecloud
