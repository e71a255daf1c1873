#include "linecloud/lifting/lifting.h"

#include <sys/stat.h>

#include <algorithm>
#include <numeric>
#include <fstream>
#include <random>
#include <set>
#include <unordered_map>

#include <gtest/gtest.h>

#include "linecloud/io/lcm_format.h"
#include "linecloud/privacy/two_key_attack.h"
#include "linecloud/testing/test_util.h"
#include "linecloud/util/error.h"
#include "linecloud/util/log.h"

namespace linecloud {
namespace {

using testing::TempDir;

LiftingKey KeyFromSeed(uint8_t seed, DirectionSet directions = DirectionSet::kSphere) {
  LiftingKey::Bytes b;
  for (size_t i = 0; i < b.size(); ++i) b[i] = static_cast<uint8_t>(seed * 31 + i);
  return LiftingKey(b, directions);
}

// The line of each point id, through the key's owner's id map.
std::unordered_map<uint64_t, PluckerLine> LinesByPointId(const LineCloud& cloud,
                                                         const LiftingKey& key) {
  std::unordered_map<uint64_t, PluckerLine> out;
  for (size_t k = 0; k < cloud.size(); ++k) out[PointIdOfLine(key, cloud.ids[k])] = cloud.lines[k];
  return out;
}

void RandomPoints(size_t n, uint64_t seed, std::vector<uint64_t>* ids,
                  std::vector<Eigen::Vector3d>* points) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 20.0);
  ids->clear();
  points->clear();
  for (size_t i = 0; i < n; ++i) {
    ids->push_back(1 + i + (i / 100) * 7);  // runs of consecutive ids with gaps
    points->emplace_back(g(rng), g(rng), g(rng) + 50.0);
  }
}

TEST(Lifting, LinesPassThroughTheirPoints) {
  std::vector<uint64_t> ids;
  std::vector<Eigen::Vector3d> points;
  RandomPoints(5000, 1, &ids, &points);
  const LiftingKey sphere = KeyFromSeed(1);
  const LiftingKey compact_key = KeyFromSeed(1, DirectionSet::kCompact256);
  const LineCloud full = LiftPoints(ids, points, sphere, {LineEncoding::kPlucker});
  const LineCloud compact = LiftPoints(ids, points, compact_key, {LineEncoding::kCompact});
  ASSERT_EQ(full.size(), ids.size());
  const auto full_lines = LinesByPointId(full, sphere);
  const auto compact_lines = LinesByPointId(compact, compact_key);
  double worst_full = 0, worst_compact = 0;
  for (size_t i = 0; i < ids.size(); ++i) {
    const double scale = points[i].norm();
    worst_full = std::max(worst_full, full_lines.at(ids[i]).DistanceTo(points[i]) / scale);
    worst_compact = std::max(worst_compact, compact_lines.at(ids[i]).DistanceTo(points[i]) / scale);
    EXPECT_TRUE(full.lines[i].IsValid(1e-12));
    // Compact directions are one of the 256 fixed ones.
    EXPECT_EQ(compact.lines[i].v, CompactDirections()[compact.compact[i].direction_index]);
  }
  EXPECT_LT(worst_full, 1e-9);
  EXPECT_LT(worst_compact, 1e-6);
}

// One point, one line: under one key every encoding stores the same line, and
// the encoding a key cannot store identically is refused.
TEST(Lifting, EveryEncodingOfAKeyStoresTheSameLine) {
  std::vector<uint64_t> ids;
  std::vector<Eigen::Vector3d> points;
  RandomPoints(3000, 11, &ids, &points);
  const LiftingKey key = KeyFromSeed(11, DirectionSet::kCompact256);
  const LineCloud full = LiftPoints(ids, points, key, {LineEncoding::kPlucker});
  const LineCloud compact = ParseLineCloud(
      SerializeLineCloud(LiftPoints(ids, points, key, {LineEncoding::kCompact})), "mem");
  ASSERT_EQ(full.ids, compact.ids);
  for (size_t k = 0; k < full.size(); ++k) {
    ASSERT_EQ(full.lines[k].v, compact.lines[k].v);
    ASSERT_EQ(full.lines[k].w, compact.lines[k].w);
  }
  const TwoLiftingsAttack attack = IntersectLinesOfEqualId(full, compact);
  EXPECT_EQ(attack.shared_ids, ids.size());
  EXPECT_TRUE(attack.points.empty());
  // A sphere key has no compact form of its lines.
  EXPECT_THROW(LiftPoints(ids, points, KeyFromSeed(11), {LineEncoding::kCompact}), Error);
  // The same key bytes with another direction set: another key (fingerprint).
  EXPECT_NE(KeyFromSeed(11).Fingerprint(), key.Fingerprint());
}

// Speck64/128's test vector from its authors' paper (key words k0, l0, l1,
// l2 = 03020100, 0b0a0908, 13121110, 1b1a1918; plaintext 3b726574 7475432d).
TEST(Lifting, Speck64MatchesItsPublishedTestVector) {
  EXPECT_EQ(
      Speck64Encrypt({0x03020100u, 0x0b0a0908u, 0x13121110u, 0x1b1a1918u}, 0x3b7265747475432dULL),
      0x8c6fa548454e028bULL);
}

TEST(Lifting, LineIdsAreAKeyedPermutationStoredInOrder) {
  std::vector<uint64_t> ids;
  std::vector<Eigen::Vector3d> points;
  RandomPoints(20000, 12, &ids, &points);
  const LiftingKey key = KeyFromSeed(12);
  const LineCloud cloud = LiftPoints(ids, points, key, {});
  EXPECT_TRUE(std::is_sorted(cloud.ids.begin(), cloud.ids.end()));
  std::set<uint64_t> point_ids(ids.begin(), ids.end()), back;
  for (const uint64_t line_id : cloud.ids) back.insert(PointIdOfLine(key, line_id));
  EXPECT_EQ(back, point_ids);  // invertible by the owner
  // Extreme ids too.
  for (const uint64_t id : {uint64_t{0}, ~uint64_t{0}, uint64_t{1} << 63}) {
    EXPECT_EQ(PointIdOfLine(key, LineIdOfPoint(key, id)), id);
  }
  // Unrelated across keys; consecutive point ids scatter.
  const std::vector<uint64_t> other = LineIdsOfPoints(KeyFromSeed(13), ids);
  const std::vector<uint64_t> mine = LineIdsOfPoints(key, ids);
  size_t same = 0, increasing = 0;
  for (size_t i = 0; i + 1 < ids.size(); ++i) {
    same += mine[i] == other[i];
    increasing += mine[i + 1] > mine[i];
  }
  EXPECT_EQ(same, 0u);
  // Each successor is larger with probability 1/2: 19 999 trials, ±5σ = ±354.
  EXPECT_NEAR(static_cast<double>(increasing), 9999.5, 354.0);
}

TEST(Lifting, DeterministicPerKeyAndIdIndependentOfOrder) {
  std::vector<uint64_t> ids;
  std::vector<Eigen::Vector3d> points;
  RandomPoints(3000, 2, &ids, &points);
  const LiftingKey key = KeyFromSeed(2);
  std::vector<Eigen::Vector3d> a(ids.size()), b(ids.size());
  KeyedDirections(key, ids, a.data(), nullptr);
  // Same ids shuffled: each id still gets its own direction.
  std::vector<size_t> order(ids.size());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), std::mt19937_64(3));
  std::vector<uint64_t> shuffled;
  for (size_t i : order) shuffled.push_back(ids[i]);
  KeyedDirections(key, shuffled, b.data(), nullptr);
  for (size_t k = 0; k < order.size(); ++k) ASSERT_EQ(b[k], a[order[k]]);
  // And one at a time.
  for (size_t i = 0; i < 50; ++i) {
    Eigen::Vector3d single;
    KeyedDirections(key, std::span<const uint64_t>(&ids[i], 1), &single, nullptr);
    ASSERT_EQ(single, a[i]);
  }
}

TEST(Lifting, AnotherKeyGivesUnrelatedDirections) {
  std::vector<uint64_t> ids;
  std::vector<Eigen::Vector3d> points;
  RandomPoints(20000, 4, &ids, &points);
  std::vector<Eigen::Vector3d> a(ids.size()), b(ids.size());
  KeyedDirections(KeyFromSeed(4), ids, a.data(), nullptr);
  KeyedDirections(KeyFromSeed(5), ids, b.data(), nullptr);
  std::set<std::tuple<double, double, double>> seen;
  for (const auto& v : a) seen.insert({v.x(), v.y(), v.z()});
  double mean_abs_cos = 0;
  for (size_t i = 0; i < ids.size(); ++i) {
    ASSERT_FALSE(seen.count({b[i].x(), b[i].y(), b[i].z()})) << "direction repeated";
    mean_abs_cos += std::abs(a[i].dot(b[i]));
  }
  // Independent uniform directions: E|cos| = 1/2.
  EXPECT_NEAR(mean_abs_cos / ids.size(), 0.5, 0.01);
}

TEST(Lifting, DirectionsAreUniformOnTheSphere) {
  const size_t n = 200000;
  std::vector<uint64_t> ids(n);
  std::iota(ids.begin(), ids.end(), 1);
  std::vector<Eigen::Vector3d> v(n);
  std::vector<uint8_t> idx(n);
  KeyedDirections(KeyFromSeed(6), ids, v.data(), idx.data());
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
  std::vector<int> z_bins(20, 0), idx_bins(256, 0);
  for (size_t i = 0; i < n; ++i) {
    ASSERT_NEAR(v[i].norm(), 1.0, 1e-14);
    mean += v[i];
    second += v[i] * v[i].transpose();
    ++z_bins[std::min(19, static_cast<int>((v[i].z() + 1.0) * 10.0))];
    ++idx_bins[idx[i]];
  }
  mean /= n;
  second /= n;
  // Uniform on S²: E[v] = 0, E[v vᵀ] = I/3; z uniform on [−1, 1].
  EXPECT_LT(mean.norm(), 0.01);
  EXPECT_LT((second - Eigen::Matrix3d::Identity() / 3.0).norm(), 0.01);
  const auto chi2 = [](const std::vector<int>& bins, double expected) {
    double c = 0;
    for (int b : bins) c += (b - expected) * (b - expected) / expected;
    return c;
  };
  // 99.99% quantiles: chi²(19) < 50, chi²(255) < 350.
  EXPECT_LT(chi2(z_bins, n / 20.0), 50.0);
  EXPECT_LT(chi2(idx_bins, n / 256.0), 350.0);
}

TEST(Lifting, CompactDirectionsAreWellSpread) {
  const auto& d = CompactDirections();
  double min_angle = 10;
  for (int i = 0; i < 256; ++i) {
    EXPECT_NEAR(d[i].norm(), 1.0, 1e-15);
    EXPECT_GT(d[i].z(), 0.0);
    Eigen::Vector3d e1, e2;
    CompactBasis(static_cast<uint8_t>(i), &e1, &e2);
    EXPECT_LT(std::abs(e1.dot(d[i])) + std::abs(e2.dot(d[i])) + std::abs(e1.dot(e2)), 1e-14);
    for (int j = 0; j < i; ++j) {
      // Lines are unoriented: compare up to sign.
      min_angle = std::min(min_angle, std::acos(std::min(1.0, std::abs(d[i].dot(d[j])))));
    }
  }
  // 256 points on a hemisphere (2π sr): ~0.157 rad spacing for a perfect packing.
  EXPECT_GT(min_angle, 0.08);
}

TEST(Lifting, RejectsBadInput) {
  const LiftingKey key = KeyFromSeed(7);
  std::vector<uint64_t> ids = {1, 2};
  std::vector<Eigen::Vector3d> points = {{0, 0, 1}, {std::nan(""), 0, 1}};
  EXPECT_THROW(LiftPoints(ids, points, key, {}), Error);
  points[1] = {1, 2, 3};
  ids[1] = 1;
  EXPECT_THROW(LiftPoints(ids, points, key, {}), Error);  // repeated id
  ids.pop_back();
  EXPECT_THROW(LiftPoints(ids, points, key, {}), Error);  // size mismatch
}

TEST(LiftingKey, FileRoundTripPermissionsAndErrors) {
  TempDir tmp;
  const LiftingKey key = LiftingKey::Generate();
  EXPECT_NE(key.bytes(), LiftingKey::Generate().bytes());
  WriteKeyFile(tmp.Path("k"), key);
  struct stat st;
  ASSERT_EQ(stat(tmp.Path("k").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  EXPECT_EQ(ReadKeyFile(tmp.Path("k")).bytes(), key.bytes());
  EXPECT_THROW(WriteKeyFile(tmp.Path("k"), key), Error);  // never overwritten
  EXPECT_EQ(key.Fingerprint(), ReadKeyFile(tmp.Path("k")).Fingerprint());
  EXPECT_NE(key.Fingerprint(), KeyFromSeed(1).Fingerprint());
  const std::vector<std::string> bad_keys = {"", "abc\n", std::string(64, 'g') + "\n",
                                             std::string(64, 'a') + "\nextra\n"};
  for (const std::string& bad : bad_keys) {
    std::ofstream(tmp.Path("bad")) << bad;
    ::chmod(tmp.Path("bad").c_str(), 0600);
    try {
      ReadKeyFile(tmp.Path("bad"));
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(tmp.Path("bad")), std::string::npos);
      EXPECT_EQ(std::string(e.what()).find("readable by other"), std::string::npos);
    }
  }
  EXPECT_THROW(ReadKeyFile(tmp.Path("missing")), Error);
  // The direction set round-trips; a legacy file (no directions line) is a
  // sphere key; a key others can read is refused unless allowed.
  const LiftingKey compact = LiftingKey::Generate(DirectionSet::kCompact256);
  WriteKeyFile(tmp.Path("c"), compact);
  EXPECT_EQ(ReadKeyFile(tmp.Path("c")).directions(), DirectionSet::kCompact256);
  EXPECT_EQ(ReadKeyFile(tmp.Path("c")).Fingerprint(), compact.Fingerprint());
  std::ofstream(tmp.Path("legacy")) << "# old\n" << ToHex(key.bytes()) << "\n";
  ::chmod(tmp.Path("legacy").c_str(), 0600);
  EXPECT_EQ(ReadKeyFile(tmp.Path("legacy")).Fingerprint(), key.Fingerprint());
  ::chmod(tmp.Path("legacy").c_str(), 0644);
  try {
    ReadKeyFile(tmp.Path("legacy"));
    ADD_FAILURE() << "accepted a key file others can read";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("readable by other users"), std::string::npos);
  }
  {
    // Allowed, it warns through the log sink (named file, nothing on the console).
    std::vector<std::pair<LogLevel, std::string>> said;
    ScopedLogSink sink(
        [&](LogLevel level, std::string_view line) { said.emplace_back(level, line); });
    EXPECT_EQ(ReadKeyFile(tmp.Path("legacy"), /*allow_shared=*/true).bytes(), key.bytes());
    ASSERT_EQ(said.size(), 1u);
    EXPECT_EQ(said[0].first, LogLevel::kWarning);
    EXPECT_EQ(said[0].second,
              tmp.Path("legacy") + " is readable by other users; run chmod 600 on it");
  }
  std::ofstream(tmp.Path("badset")) << "directions cube\n" << ToHex(key.bytes()) << "\n";
  ::chmod(tmp.Path("badset").c_str(), 0600);
  EXPECT_THROW(ReadKeyFile(tmp.Path("badset")), Error);
}

TEST(Lifting, NoPointCoordinateInTheFile) {
  std::vector<uint64_t> ids;
  std::vector<Eigen::Vector3d> points;
  RandomPoints(2000, 8, &ids, &points);
  const LiftingKey key = KeyFromSeed(8, DirectionSet::kCompact256);
  testing::ExpectNoCoordinates(SerializeLineCloud(LiftPoints(ids, points, KeyFromSeed(8), {})),
                               points);
  for (const LineEncoding encoding : {LineEncoding::kPlucker, LineEncoding::kCompact}) {
    testing::ExpectNoCoordinates(SerializeLineCloud(LiftPoints(ids, points, key, {encoding})),
                                 points);
  }
}

}  // namespace
}  // namespace linecloud
