// The options of the density attack and of the owner's audit, described
// once (io/option_table.h): `linecloud attack` / `audit` make their flags
// from these tables and Python's `attack` / `audit` their keyword arguments,
// so the two take the same names, ranges and defaults.
#pragma once

#include <vector>

#include "linecloud/io/option_table.h"
#include "linecloud/privacy/audit.h"
#include "linecloud/privacy/density_attack.h"

namespace linecloud {

// neighbours, refine_rounds, refine_neighbours, min_shared, threads, max_seconds.
const std::vector<OptionField<DensityAttackOptions>>& AttackOptionTable();

// The attack's options (on AuditOptions::attack), then the audit's own figures:
// metric_scale, density_attack, crossing_tolerance, recovered_within. (The
// map, the model, the other map, the output folder and the key are the
// command's arguments, not options.)
const std::vector<OptionField<AuditOptions>>& AuditOptionTable();

}  // namespace linecloud
