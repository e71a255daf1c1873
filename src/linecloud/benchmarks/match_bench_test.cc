#include "linecloud/benchmarks/match_bench.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

namespace linecloud {
namespace {

// `bench match` on seeded synthetic descriptors: one typed row per map size and index, most exact
// matches found by each index, and the same figures in the JSON and the table.
TEST(MatchBench, TypedRowsAsJsonAndMarkdown) {
  MatchBenchOptions o;
  o.map_sizes = {3000};
  o.queries = 400;
  o.recall_queries = 200;
  o.kinds = {DescriptorIndexKind::kIvf, DescriptorIndexKind::kFlann};
  o.threads = {1};
  const std::vector<MatchBenchRow> rows = RunMatchBench(o);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].index, DescriptorIndexKindName(DescriptorIndexKind::kIvf));
  EXPECT_EQ(rows[1].index, DescriptorIndexKindName(DescriptorIndexKind::kFlann));
  for (const MatchBenchRow& r : rows) {
    EXPECT_EQ(r.map_size, 3000u);
    EXPECT_FALSE(r.real);
    EXPECT_EQ(r.queries, 400u);
    EXPECT_EQ(r.recall_queries, 200u);
    EXPECT_GT(r.exact_matches, 0u);  // half the queries are noisy copies of map descriptors
    ASSERT_EQ(r.ms_by_threads.count(1), 1u);
    EXPECT_GT(r.recall, 0.5) << r.index;
    EXPECT_LE(r.recall, 1.0) << r.index;
  }
  const nlohmann::json j = ToJson(rows);
  EXPECT_EQ(j[1]["descriptors"], "synthetic");
  EXPECT_EQ(j[1]["ms_by_threads"]["1"].get<double>(), rows[1].ms_by_threads.at(1));
  EXPECT_EQ(j[0]["recall"].get<double>(), rows[0].recall);
  const std::string md = MatchBenchMarkdown(rows);
  EXPECT_NE(md.find("bench match: 400 query descriptors (synthetic"), std::string::npos) << md;
  EXPECT_NE(md.find(fmt::format("| 3000 | {} | {:.1f} |", rows[1].index, rows[1].index_build_s)),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| - |"), std::string::npos) << md;  // no 2-thread run
}

}  // namespace
}  // namespace linecloud
