// `linecloud bench attack`: the density attack's time and recovery on seeded
// dense façades (synthetic/surfaces.h) of growing size, lifted with a fixed
// key, so that the figures are reproducible run to run.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace linecloud {

struct AttackBenchOptions {
  std::vector<int> sizes = {20000, 100000};
  double texture_share = 0.8;
  uint64_t seed = 7;
  int threads = 0;  // 0: all cores
  std::function<void(const std::string&)> progress;
};

// One size's figures: the attack's time, and the share of the secret points it recovers within
// 0.5 / 1 / 2 % of the façade's diagonal.
struct AttackBenchRow {
  size_t lines = 0;
  int threads = 0;
  double seconds = 0, us_per_line = 0;
  double within_half_percent = 0, within_1_percent = 0, within_2_percent = 0;
};

// One row per size.
std::vector<AttackBenchRow> RunAttackBench(const AttackBenchOptions& options);
// The rows as JSON (keys "lines", "threads", "seconds", "us_per_line", "within_0.5_percent",
// "within_1_percent", "within_2_percent") and as a Markdown table.
nlohmann::json ToJson(const std::vector<AttackBenchRow>& rows);
std::string AttackBenchMarkdown(const std::vector<AttackBenchRow>& rows);

}  // namespace linecloud
