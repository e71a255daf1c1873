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

// One row per size: lines, threads, seconds, share within 0.5 / 1 / 2 % of the diagonal.
nlohmann::json RunAttackBench(const AttackBenchOptions& options);

}  // namespace linecloud
