#include "linecloud/privacy/audit_report.h"

#include <gtest/gtest.h>

#include "linecloud/util/error.h"

namespace linecloud {
namespace {

AuditReport SomeAudit() {
  AuditReport r;
  r.map = "map.lcm";
  r.model = "model";
  r.encoding = "float64";
  r.lines = 100;
  r.model_points = 120;
  r.diagonal = 2.5;
  r.metric_scale = 0.01;
  DensityAttackReport a;
  a.method = "density";
  a.line_neighbours = 20;
  a.refine_rounds = 2;
  a.refine_neighbours = 10;
  a.lines_without_votes = 3;
  a.search = "grid";
  a.search_radius = 0.004;
  a.lines_short_of_neighbours = 7;
  a.seconds = 0.5;
  a.recovery.points = 100;
  a.recovery.diagonal = 2.5;
  a.recovery.median_error = 0.02;
  a.recovery.median_error_diagonal_percent = 0.8;
  a.recovery.within_diagonal_percent = {{0.5, 0.25}, {1, 0.5}, {2, 0.75}};
  a.recovery.metric_scale = 0.01;
  a.recovery.median_error_m = 0.0002;
  a.recovery.within_m = {{0.01, 0.9}, {0.1, 1}};
  r.density_attack = a;
  PairingReport self;
  self.pairing = "own crossings";
  self.pairs = 7;
  self.intersections = 7;
  self.recovered = 4;
  self.share_recovered = 0.04;
  r.pairing_attacks.crossing_tolerance_diagonal = 1e-3;
  r.pairing_attacks.recovered_within_diagonal = 1e-4;
  r.pairing_attacks.self_crossings = self;
  PairingReport by_id = self;
  by_id.pairing = "equal ids";
  by_id.recovered_beyond_own = 0;
  by_id.share_recovered_beyond_own = 0.0;
  r.pairing_attacks.by_id = by_id;
  r.pairing_attacks.most_recovered_beyond_own = 0;
  r.pairing_attacks.share_most_recovered_beyond_own = 0.0;
  return r;
}

std::string ErrorOf(const nlohmann::json& j) {
  try {
    AuditReportFromJson(j, "a.json");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(AuditReport, ReadsBackWhatItWrites) {
  const nlohmann::json j = ToJson(SomeAudit());
  const AuditReport back = AuditReportFromJson(j, "a.json");
  EXPECT_EQ(nlohmann::json(ToJson(back)), j);
  EXPECT_EQ(AuditMarkdown(back), AuditMarkdown(SomeAudit()));
  EXPECT_EQ(back.density_attack->recovery.within_m.back().first, 0.1);
  EXPECT_FALSE(back.two_keys.has_value());
  EXPECT_FALSE(back.pairing_attacks.by_descriptor.has_value());
}

// What a damaged or forged report.json gets: the field's path and why, never a table that
// shows impossible figures.
TEST(AuditReport, ReadingNamesTheBadField) {
  const nlohmann::json good = ToJson(SomeAudit());
  auto changed = [&](const nlohmann::json::json_pointer& at, const nlohmann::json& value) {
    nlohmann::json j = good;
    if (value.is_discarded()) {
      j[at.parent_pointer()].erase(at.back());
    } else {
      j[at] = value;
    }
    return ErrorOf(j);
  };
  using P = nlohmann::json::json_pointer;
  const nlohmann::json gone(nlohmann::json::value_t::discarded);
  EXPECT_EQ(changed(P("/lines"), -3), "a.json.lines: -3 is not a count (an integer >= 0)");
  EXPECT_EQ(changed(P("/lines"), 2.5), "a.json.lines: 2.5 is not a count (an integer >= 0)");
  EXPECT_EQ(changed(P("/map"), gone), "a.json.map: missing");
  EXPECT_EQ(changed(P("/density_attack/recovery/within_diagonal_percent/1"), 1.5),
            "a.json.density_attack.recovery.within_diagonal_percent.1: 1.5 is not a share in [0, "
            "1]");
  EXPECT_EQ(changed(P("/density_attack/recovery/within_diagonal_percent"), {{"x", 0.5}}),
            "a.json.density_attack.recovery.within_diagonal_percent.x: \"x\" is not a positive "
            "threshold");
  EXPECT_EQ(changed(P("/pairing_attacks/by_id/share_recovered"), -0.1),
            "a.json.pairing_attacks.by_id.share_recovered: -0.1 is not a share in [0, 1]");
  EXPECT_EQ(changed(P("/pairing_attacks/self_crossings/recovered"), 101),
            "a.json.pairing_attacks.self_crossings.recovered: 101 points recovered from a map of "
            "100 lines");
  EXPECT_EQ(changed(P("/density_attack/lines_without_votes"), 1000),
            "a.json.density_attack.lines_without_votes: 1000 lines without votes in a map of 100 "
            "lines");
  EXPECT_EQ(changed(P("/density_attack/search"), "kd-tree"),
            "a.json.density_attack.search: \"kd-tree\" is not a search (every pair, grid)");
  EXPECT_EQ(changed(P("/density_attack/seconds"), "1"),
            "a.json.density_attack.seconds: \"1\" is not a number");
  EXPECT_EQ(changed(P("/pairing_attacks"), gone), "a.json.pairing_attacks: missing");
  EXPECT_EQ(ErrorOf(nlohmann::json::array()), "a.json: not an object");
}

// Names from the file cannot break report.md's tables or start a heading.
TEST(AuditReport, MarkdownKeepsFileTextInItsCell) {
  AuditReport r = SomeAudit();
  r.pairing_attacks.by_id->pairing = "a | b\n# c";
  r.map = "x\n## y";
  const std::string md = AuditMarkdown(r);
  EXPECT_NE(md.find("| a \\| b # c |"), std::string::npos) << md;
  EXPECT_NE(md.find("# Privacy audit of x ## y\n"), std::string::npos) << md;
  EXPECT_EQ(md.find("\n## y"), std::string::npos);
}

}  // namespace
}  // namespace linecloud
