// `linecloud bench match`: matching query descriptors to a map's, exact
// (MatchDescriptors) against the approximate index (DescriptorIndex), on
// seeded SIFT-like bytes: RootSIFT of gamma-distributed gradient histograms
// for the map; queries half noisy copies of map descriptors (each bin scaled
// by exp(N(0, 0.2)) plus N(0, 3), renormalised) and half unrelated ones. One
// thread.
#pragma once

#include <cstdint>
#include <vector>

#include <nlohmann/json.hpp>

#include "linecloud/features/descriptor_index.h"

namespace linecloud {

struct MatchBenchOptions {
  std::vector<size_t> map_sizes = {100000};
  size_t queries = 8000;
  size_t recall_queries = 1000;  // queries also matched exactly, for the recall
  uint64_t seed = 1;
  DescriptorIndexOptions index;

  void Check() const;
};

// Rows per map size: build_s, ann_ms (all queries), exact_ms_per_query,
// exact and approximate matches on the recall queries, recall.
nlohmann::json RunMatchBench(const MatchBenchOptions& options);

}  // namespace linecloud
