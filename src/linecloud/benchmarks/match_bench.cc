#include "linecloud/benchmarks/match_bench.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <set>

#include <fmt/format.h>

#include "linecloud/features/matching.h"
#include "linecloud/util/clock.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using Clock = std::chrono::steady_clock;

// RootSIFT bytes of `v` (non-negative): sqrt(v / |v|₁) · 512, rounded, clamped.
void RootSiftBytes(const double* v, uint8_t* out) {
  double l1 = 0;
  for (int i = 0; i < 128; ++i) l1 += v[i];
  for (int i = 0; i < 128; ++i) {
    out[i] = static_cast<uint8_t>(std::clamp(std::round(512 * std::sqrt(v[i] / l1)), 0.0, 255.0));
  }
}

void RandomDescriptor(std::mt19937_64& rng, uint8_t* out) {
  std::gamma_distribution<double> gamma(0.5, 1.0);
  double v[128];
  for (double& x : v) x = gamma(rng) + 1e-9;
  RootSiftBytes(v, out);
}

// A noisy observation of `in`: per-bin gain and offset, back on the L2 sphere.
void NoisyCopy(std::mt19937_64& rng, const uint8_t* in, uint8_t* out) {
  std::normal_distribution<double> gain(0.0, 0.2), offset(0.0, 3.0);
  double v[128], norm = 0;
  for (int i = 0; i < 128; ++i) {
    v[i] = std::max(0.0, in[i] * std::exp(gain(rng)) + offset(rng));
    norm += v[i] * v[i];
  }
  const double s = norm > 0 ? 512 / std::sqrt(norm) : 0;
  for (int i = 0; i < 128; ++i)
    out[i] = static_cast<uint8_t>(std::clamp(std::round(v[i] * s), 0.0, 255.0));
}

}  // namespace

void MatchBenchOptions::Check() const {
  if (map_sizes.empty()) Fail("bench match: no map size");
  for (const size_t n : map_sizes) {
    if (n < 2 || n > 20000000) Fail("bench match: map size {} is out of range [2, 2e7]", n);
  }
  if (queries < 1 || recall_queries < 1 || recall_queries > queries) {
    Fail("bench match: need 1 <= recall queries ({}) <= queries ({})", recall_queries, queries);
  }
  index.Check();
}

nlohmann::json RunMatchBench(const MatchBenchOptions& o) {
  o.Check();
  nlohmann::json rows = nlohmann::json::array();
  for (const size_t n : o.map_sizes) {
    std::mt19937_64 rng(o.seed);
    std::vector<uint8_t> map(n * 128), query(o.queries * 128);
    for (size_t i = 0; i < n; ++i) RandomDescriptor(rng, map.data() + i * 128);
    for (size_t i = 0; i < o.queries; ++i) {
      if (i % 2 == 0) {
        NoisyCopy(rng, map.data() + (rng() % n) * 128, query.data() + i * 128);
      } else {
        RandomDescriptor(rng, query.data() + i * 128);
      }
    }
    const DescriptorMatchOptions match;
    auto t = Clock::now();
    const DescriptorIndex index(map, o.index);
    const double build_s = SecondsSince(t);
    t = Clock::now();
    const std::vector<DescriptorMatch> approx = index.Match(query, match);
    const double ann_ms = 1e3 * SecondsSince(t);
    const std::span<const uint8_t> recall_part(query.data(), o.recall_queries * 128);
    t = Clock::now();
    const std::vector<DescriptorMatch> exact = MatchDescriptors(recall_part, map, match);
    const double exact_ms = 1e3 * SecondsSince(t);
    std::set<std::pair<int, int>> found;
    for (const DescriptorMatch& m : approx) found.insert({m.query, m.map});
    size_t hits = 0;
    for (const DescriptorMatch& m : exact) hits += found.count({m.query, m.map});
    size_t approx_on_recall = 0;
    for (const DescriptorMatch& m : approx) approx_on_recall += m.query < int(o.recall_queries);
    rows.push_back({{"map_size", n},
                    {"queries", o.queries},
                    {"index_build_s", build_s},
                    {"ann_ms", ann_ms},
                    {"exact_ms_per_query", exact_ms / o.recall_queries},
                    {"exact_ms_extrapolated", exact_ms / o.recall_queries * o.queries},
                    {"recall_queries", o.recall_queries},
                    {"exact_matches", exact.size()},
                    {"approx_matches", approx_on_recall},
                    {"recall", exact.empty() ? 1.0 : double(hits) / exact.size()}});
  }
  return rows;
}

}  // namespace linecloud
