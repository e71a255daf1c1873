#include "linecloud/privacy/attack_option_table.h"

namespace linecloud {
namespace {

using json = nlohmann::json;

OptionField<DensityAttackOptions> AttackInteger(std::string name, std::string help, double min,
                                                double max,
                                                std::function<int&(DensityAttackOptions&)> member) {
  OptionField<DensityAttackOptions> f = MemberField<DensityAttackOptions, int>(
      std::move(name), OptionType::kInteger, std::move(help), std::move(member));
  f.min = min;
  f.max = max;
  return f;
}

std::vector<OptionField<DensityAttackOptions>> MakeAttackTable() {
  using O = DensityAttackOptions;
  std::vector<OptionField<O>> t;
  t.push_back(AttackInteger(
      "neighbours",
      "K nearest lines voting for each line's point (0: min(500, 5 % of the lines), as published)",
      0, 1 << 30, [](O& o) -> int& { return o.line_neighbours; }));
  t.push_back(AttackInteger("refine_rounds", "Refinement rounds", 0, 20,
                            [](O& o) -> int& { return o.refine_rounds; }));
  t.push_back(AttackInteger("refine_neighbours",
                            "Neighbours of the refinement (line-to-point and point-to-line)", 1,
                            1 << 30, [](O& o) -> int& { return o.refine_neighbours; }));
  t.push_back(AttackInteger("min_shared",
                            "Use the two refinement sets' intersection when larger than this", 0,
                            1 << 30, [](O& o) -> int& { return o.min_shared; }));
  t.push_back(AttackInteger(
      "exact_search_lines",
      "Up to this many lines every pair is compared (the published search, n²); beyond, a grid of "
      "the scene's box (exact within radii holding the K nearest of 95 % of sampled lines)",
      0, 1 << 30, [](O& o) -> int& { return o.exact_search_lines; }));
  t.push_back(AttackInteger("threads", "Threads (0: all cores)", 0, 1024,
                            [](O& o) -> int& { return o.threads; }));
  OptionField<O> seconds = MemberField<O, double>(
      "max_seconds", OptionType::kNumber,
      "Stop (with an error giving the projected time) after this long; the exact search's cost "
      "grows as the square of the lines (0: no limit)",
      [](O& o) -> double& { return o.max_seconds; });
  seconds.min = 0;
  seconds.max = 1e9;
  t.push_back(std::move(seconds));
  return t;
}

OptionField<AuditOptions> AuditNumber(std::string name, std::string help, double min, double max,
                                      bool open, std::function<double&(AuditOptions&)> member) {
  OptionField<AuditOptions> f = MemberField<AuditOptions, double>(
      std::move(name), OptionType::kNumber, std::move(help), std::move(member));
  f.min = min;
  f.max = max;
  f.min_open = f.max_open = open;
  return f;
}

std::vector<OptionField<AuditOptions>> MakeAuditTable() {
  std::vector<OptionField<AuditOptions>> t;
  for (const OptionField<DensityAttackOptions>& a : AttackOptionTable()) {
    OptionField<AuditOptions> f;
    static_cast<OptionDescription&>(f) = a;
    f.get = [get = a.get](const AuditOptions& o) { return get(o.attack); };
    f.set = [set = a.set](AuditOptions& o, const json& v) { set(o.attack, v); };
    t.push_back(std::move(f));
  }
  t.push_back(AuditNumber("metric_scale", "Metres per model unit: also report errors in metres", 0,
                          1e12, false, [](AuditOptions& o) -> double& { return o.metric_scale; }));
  OptionField<AuditOptions> density;
  density.name = "density_attack";
  density.type = OptionType::kBool;
  density.help =
      "Run the density attack (off: only the pairing attacks and, with another map, "
      "the two-key attack)";
  density.get = [](const AuditOptions& o) { return json(!o.skip_density_attack); };
  density.set = [](AuditOptions& o, const json& v) { o.skip_density_attack = !v.get<bool>(); };
  t.push_back(std::move(density));
  t.push_back(AuditNumber(
      "crossing_tolerance",
      "Pairing attacks: intersect lines passing within this share of the scene diagonal of each "
      "other",
      0, 0.1, true, [](AuditOptions& o) -> double& { return o.crossing_tolerance; }));
  t.push_back(
      AuditNumber("recovered_within",
                  "Pairing attacks: a point counts as recovered within this share of the diagonal",
                  0, 0.1, true, [](AuditOptions& o) -> double& { return o.recovered_within; }));
  return t;
}

}  // namespace

const std::vector<OptionField<DensityAttackOptions>>& AttackOptionTable() {
  static const std::vector<OptionField<DensityAttackOptions>> table = MakeAttackTable();
  return table;
}

const std::vector<OptionField<AuditOptions>>& AuditOptionTable() {
  static const std::vector<OptionField<AuditOptions>> table = MakeAuditTable();
  return table;
}

}  // namespace linecloud
