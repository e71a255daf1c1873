// `linecloud eval privacy`: the privacy/accuracy trade-off of the liftings on
// a prepared dataset. For each lifting (privacy/map_lifting.h): the density
// attack on every group map as `lift` would write it, scored against the
// map's points (what an attacker recovers), and `eval run` on those maps
// (what localization keeps: the paper's protocol and direct matching of the
// query photos). Writes tradeoff.json, tradeoff.md and tradeoff.png (attack
// recovery against localization error, one point per lifting) in OUT, and
// each lifting's eval report in OUT/<lifting>/.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "linecloud/privacy/density_attack.h"
#include "linecloud/privacy/map_lifting.h"

namespace linecloud {

struct PrivacyTradeoffOptions {
  std::string work_dir, out_dir;
  // Default: plain; uniform 50/75/90/95 %; balanced 50/75/90/95 %;
  // resist 0.2 and 0.1; compact.
  std::vector<MapLifting> liftings;
  std::vector<std::string> methods = {"p6L", "p4L+u"};
  bool direct_matching = true;
  DensityAttackOptions attack;
  std::function<void(const std::string&)> progress;

  void Check() const;
};

std::vector<MapLifting> DefaultTradeoffLiftings();
// The `--quick` preset: plain, uniform and balanced 90 %, resist 0.2.
std::vector<MapLifting> QuickTradeoffLiftings();

nlohmann::ordered_json RunPrivacyTradeoff(const PrivacyTradeoffOptions& options);

// tradeoff.md and tradeoff.png from OUT/tradeoff.json (what RunPrivacyTradeoff
// ends with; `eval privacy --render OUT` redoes it).
void RenderPrivacyTradeoff(const std::string& out_dir);

}  // namespace linecloud
