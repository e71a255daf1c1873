#include "linecloud/serve/load_report.h"

#include <gtest/gtest.h>

namespace linecloud {
namespace {

// `bench serve`'s report: its JSON layout and docs/serve.md's table rows.
TEST(LoadReport, AsJsonAndMarkdown) {
  LoadReport r;
  r.map = "fountain";
  r.client_features = 8192;
  r.workers = 2;
  r.queue = 64;
  r.hardware_threads = 2;
  r.levels.push_back({"features", 8, 12, 3.25, 610.4, 1200.6, {{200, 11}, {503, 1}}, 11});
  r.leak_check = LeakCheck{150, 210.5, 211.0, {{200, 150}}};
  AttackSoak a;
  a.seconds = 5;
  a.attackers = 4;
  a.dribblers = 50;
  a.alone = {"features", 1, 9, 1.8, 540, 560, {{200, 9}}, 9};
  a.under_attack = {"features", 1, 8, 1.6, 600, 700, {{200, 8}}, 8};
  a.p99_ratio = 1.25;
  a.hostile_requests = 900;
  a.hostile_statuses["nested JSON"] = {{400, 450}};
  a.hostile_statuses["no answer"] = {{0, 3}};
  r.attack = a;
  const nlohmann::json j = ToJson(r);
  EXPECT_EQ(j["levels"][0]["statuses"], nlohmann::json({{"200", 11}, {"503", 1}}));
  EXPECT_EQ(j["leak_check"]["requests"], 150);
  EXPECT_EQ(j["attack"]["hostile_statuses"]["no answer"]["0"], 3);
  EXPECT_EQ(j["attack"]["under_attack"]["p99_ms"], 700);
  EXPECT_FALSE(j.contains("rig_frames"));
  const std::string md = LoadMarkdown(r);
  EXPECT_NE(md.find("| features | 8 | 12 | 3.2 | 610 | 1201 | {\"200\":11,\"503\":1} | 11 |\n"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("150 more feature requests: resident memory 210.5 MB before, 211.0 MB after"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| under_attack | 8 | 600.0 | 700.0 | {\"200\":8} |\n"), std::string::npos)
      << md;
  EXPECT_NE(md.find("p99 under attack / alone: 1.25"), std::string::npos) << md;
}

}  // namespace
}  // namespace linecloud
