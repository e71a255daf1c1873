#include "linecloud/features/descriptor_index.h"

#include <random>
#include <set>

#include <gtest/gtest.h>

#include "linecloud/features/matching.h"
#include "linecloud/testing/test_util.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

// Clustered byte descriptors on the 512 sphere; queries are noisy members.
void MakeData(size_t n, size_t nq, std::vector<uint8_t>* map, std::vector<uint8_t>* query) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> noise(0, 4);
  const auto put = [&](std::vector<double> v, uint8_t* out) {
    double norm = 0;
    for (double& x : v) norm += x * x;
    for (int i = 0; i < 128; ++i)
      out[i] =
          static_cast<uint8_t>(std::clamp(std::round(v[i] * 512 / std::sqrt(norm)), 0.0, 255.0));
  };
  map->resize(n * 128);
  query->resize(nq * 128);
  for (size_t i = 0; i < n; ++i) {
    std::vector<double> v(128);
    for (double& x : v) x = u(rng) * u(rng);
    put(v, map->data() + i * 128);
  }
  for (size_t i = 0; i < nq; ++i) {
    const uint8_t* src = map->data() + (rng() % n) * 128;
    std::vector<double> v(128);
    for (int k = 0; k < 128; ++k) v[k] = std::max(0.0, src[k] + noise(rng));
    put(v, query->data() + i * 128);
  }
}

TEST(DescriptorIndex, FindsTheExactRatioTestMatchesAndSurvivesASaveAndLoad) {
  std::vector<uint8_t> map, query;
  MakeData(3000, 400, &map, &query);
  const DescriptorIndex index(map, {});
  const DescriptorMatchOptions options;
  const auto exact = MatchDescriptors(query, map, options);
  const auto approx = index.Match(query, options);
  ASSERT_GT(exact.size(), 300u);
  std::set<std::pair<int, int>> found;
  for (const auto& m : approx) found.insert({m.query, m.map});
  size_t hits = 0;
  for (const auto& m : exact) hits += found.count({m.query, m.map});
  EXPECT_GE(hits, 0.95 * exact.size());
  EXPECT_LE(approx.size(),
            exact.size() + 5);  // the same tests decide: no extra matches to speak of

  testing::TempDir tmp;
  index.Save(tmp.Path("map.flann"));
  const auto loaded = DescriptorIndex::Load(tmp.Path("map.flann"), map, {});
  ASSERT_NE(loaded, nullptr);
  const auto again = loaded->Match(query, options);
  ASSERT_EQ(again.size(), approx.size());
  for (size_t i = 0; i < again.size(); ++i) EXPECT_EQ(again[i].map, approx[i].map);
  // Other descriptors: the saved index is stale and not used.
  std::vector<uint8_t> other = map;
  other[17] ^= 1;
  EXPECT_EQ(DescriptorIndex::Load(tmp.Path("map.flann"), other, {}), nullptr);
  EXPECT_EQ(DescriptorIndex::Load(tmp.Path("missing.flann"), map, {}), nullptr);
  WriteFileAtomically(tmp.Path("junk.flann"), [](std::ostream& os) { os << "junk"; });
  EXPECT_EQ(DescriptorIndex::Load(tmp.Path("junk.flann"), map, {}), nullptr);
}

}  // namespace
}  // namespace linecloud
