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
#include <map>
#include <optional>
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

// What the density attack recovers from a lifting's group maps, pooled over the maps.
struct TradeoffAttack {
  double lines_per_map = 0;
  // Shares of the maps' points recovered within 0.5 / 1 / 2 % of the map's diagonal, and within
  // 5 cm (metric works only).
  double within_half_percent = 0, within_1_percent = 0, within_2_percent = 0;
  std::optional<double> within_5cm;
  double attack_seconds = 0;
};

// What localization keeps: one method's figures under one protocol.
struct TradeoffLocalization {
  int localized = 0, queries = 0;
  double median_rotation_deg = 0, median_translation = 0;
};

struct TradeoffRow {
  std::string lifting;  // MapLifting::Name()
  TradeoffAttack attack;
  // By method: `eval run`'s paper protocol, and direct matching when it ran.
  std::map<std::string, TradeoffLocalization> paper_protocol, direct_matching;
};

// tradeoff.json: the first row is the plain lifting.
struct PrivacyTradeoffReport {
  std::string dataset, units;
  std::vector<std::string> methods;
  std::vector<TradeoffRow> liftings;
};

nlohmann::ordered_json ToJson(const PrivacyTradeoffReport& report);
// Errors name `where` and the field.
PrivacyTradeoffReport PrivacyTradeoffFromJson(const nlohmann::json& j, const std::string& where);

PrivacyTradeoffReport RunPrivacyTradeoff(const PrivacyTradeoffOptions& options);

// tradeoff.md and tradeoff.png from OUT/tradeoff.json (what RunPrivacyTradeoff
// ends with; `eval privacy --render OUT` redoes it).
void RenderPrivacyTradeoff(const std::string& out_dir);

}  // namespace linecloud
