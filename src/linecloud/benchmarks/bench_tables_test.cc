#include <gtest/gtest.h>

#include "linecloud/benchmarks/localization_bench.h"
#include "linecloud/benchmarks/solver_bench.h"

namespace linecloud {
namespace {

// `bench solvers`' table: a peer's row gives our time over its time.
TEST(BenchTables, SolverRowsAsJsonAndMarkdown) {
  SolverBenchReport r;
  r.options.seed = 7;
  r.options.instances = 50;
  r.options.min_seconds = 0.5;
  r.rows.push_back({"p3P", "linecloud", 0.3, 0.32, 1.9, 100, -14.8, 50});
  r.rows.push_back({"", "opengv-p3p_kneip", 1.2, 0, 4, 100, -14.4, 50});
  const std::string md = SolverBenchMarkdown(r);
  EXPECT_EQ(md.rfind("fixed seed 7, 50 noise-free instances per method, >= 0.5 s timing each", 0),
            0u)
      << md;
  EXPECT_NE(md.find("| p3P                           | linecloud                     |     0.300 "
                    "|    0.320 |      1.90 |   100.00 |      -14.8 |                |\n"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| opengv-p3p_kneip              |     1.200 |          |      4.00 |   "
                    "100.00 |      -14.4 |          0.25x |\n"),
            std::string::npos)
      << md;
  const nlohmann::json j = ToJson(r);
  EXPECT_EQ(j["seed"], 7);
  ASSERT_EQ(j["rows"].size(), 2u);
  EXPECT_EQ(j["rows"][0]["api_us_per_call"], 0.32);
  EXPECT_FALSE(j["rows"][1].contains("api_us_per_call"));  // a peer has no API time
}

// `bench localize`' table: the settings, each method against its counterpart
// (its refined error and Cramér–Rao bound), and a row without queries.
TEST(BenchTables, LocalizationRowsAsJsonAndMarkdown) {
  LocalizationBenchReport r;
  r.options.queries = 4;
  r.options.instance.inlier_ratio = 0.5;
  r.options.instance.match_scores = true;
  LocalizationBenchRow p3p, p6l;
  p3p.method = "p3P";
  p3p.counterpart = "p6L";
  p3p.queries = 4;
  p3p.localized = 3;
  p3p.median_rotation_deg[0] = 0.1;
  p3p.median_rotation_deg[1] = 0.02;
  p3p.rotation_bound_deg = 0.01;
  p3p.counterpart_rotation_bound_deg = 0.02;
  p6l = p3p;
  p6l.method = "p6L";
  p6l.counterpart = "p3P";
  p6l.median_rotation_deg[0] = 0.2;
  p6l.median_rotation_deg[1] = 0.04;
  p6l.rotation_bound_deg = 0.02;
  p6l.counterpart_rotation_bound_deg = 0.01;
  r.rows = {p3p, p6l};
  const std::string md = LocalizationBenchMarkdown(r);
  EXPECT_NE(md.find("seed 1, 4 queries per method, 500 correspondences, 50 % inliers"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("match ratios as on real photos, PROSAC samples"), std::string::npos) << md;
  EXPECT_NE(md.find("| p3P | 75.0 % | 0 | 0.1000 / 0.0200 | 0.0100 |"), std::string::npos) << md;
  EXPECT_NE(md.find("| 0.50x p6L (0.50x) |\n"), std::string::npos) << md;
  EXPECT_NE(md.find("| 2.00x p3P (2.00x) |\n"), std::string::npos) << md;
  r.rows[0].queries = 0;
  r.rows[0].localized = 0;
  EXPECT_NE(LocalizationBenchMarkdown(r).find("| p3P | 0.0 % |"), std::string::npos);
  const nlohmann::json j = ToJson(r);
  EXPECT_EQ(j["inlier_ratio"], 0.5);
  EXPECT_EQ(j["match_scores"], true);
  EXPECT_EQ(j["rows"][1]["median_rotation_deg"]["refined"], 0.04);
}

}  // namespace
}  // namespace linecloud
