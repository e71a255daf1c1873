// The options of `lift`, described once (io/option_table.h): the command
// line's flags and Python's `lift` keywords are made from this table. A lift
// is LiftModelOptions (the model, the output, the key, the descriptors, the
// identity rule) with a MapLifting (the sparsification, the attack-aware
// selection, the encoding), as LiftModelWith takes them.
#pragma once

#include <vector>

#include "linecloud/io/lift_model.h"
#include "linecloud/io/option_table.h"
#include "linecloud/privacy/map_lifting.h"

namespace linecloud {

struct LiftSettings {
  LiftModelOptions options;  // the paths are the command's arguments, not options
  MapLifting lifting;
};

// descriptor, compact, force, gravity, sparsify, sparsify_mode, resist_attack,
// same_place, allow_shared_key.
const std::vector<OptionField<LiftSettings>>& LiftOptionTable();

}  // namespace linecloud
