#include "linecloud/lifting/identity.h"

#include <random>

#include <gtest/gtest.h>

#include "linecloud/geometry/line_grid.h"
#include "linecloud/lifting/release_ledger.h"
#include "linecloud/testing/test_util.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

// A synthetic model: points in a box, each seen by two of 10 images (one
// observation per image, keypoint = point index), image centres on a circle.
struct Model {
  std::vector<uint64_t> ids;
  std::vector<Eigen::Vector3d> points;
  std::vector<uint32_t> start;
  std::vector<uint64_t> observations;
  std::vector<std::pair<uint64_t, Eigen::Vector3d>> images;
  std::vector<uint64_t> sketches;  // empty: no descriptors
  IdentityInput Input() const { return {ids, points, start, observations, images, sketches}; }
};

Model MakeModel(const LiftingKey& key, size_t n, uint64_t first_id = 1,
                const std::string& image_prefix = "img", double feature_shift = 0) {
  const ObservationHasher h(key);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-5, 5);
  Model m;
  std::vector<uint64_t> image_hash;
  for (int i = 0; i < 10; ++i) {
    // The image's features: 20 keypoints at (100 i + 3 + shift, k).
    std::vector<Eigen::Vector2d> first;
    for (int k = 0; k < 16; ++k) first.emplace_back(100.0 * i + 3 + feature_shift, k);
    image_hash.push_back(h.ImageFeatures(image_prefix + std::to_string(i) + ".jpg", 20, first));
    m.images.push_back({image_hash.back(), Eigen::Vector3d(20 * std::cos(i), 20 * std::sin(i), 3)});
  }
  for (int i = 0; i < 10; ++i) {
    // Also by name, as lift lists them: a version with other features keeps the names.
    m.images.push_back({h.Image(image_prefix + std::to_string(i) + ".jpg"), m.images[i].second});
  }
  std::uniform_int_distribution<uint64_t> bits;
  for (size_t k = 0; k < n; ++k) {
    m.sketches.push_back(bits(rng) | 1);
    m.ids.push_back(first_id + k);
    m.points.emplace_back(u(rng), u(rng), u(rng));
    m.start.push_back(static_cast<uint32_t>(m.observations.size()));
    for (const size_t i : {k % 10, (k + 3) % 10}) {
      m.observations.push_back(h.Observation(image_hash[i], static_cast<uint32_t>(k)));
    }
  }
  m.start.push_back(static_cast<uint32_t>(m.observations.size()));
  return m;
}

ReleaseLedger Release(const Model& m, const IdentityResult& r) {
  ReleaseLedger ledger;
  std::vector<size_t> all(m.ids.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = i;
  RecordRelease(m.Input(), r, all, &ledger);
  return ledger;
}

const LiftingKey kKey(LiftingKey::Bytes{7, 1, 2, 3});

double RobustBoxDiagonalForTest(const std::vector<Eigen::Vector3d>& points) {
  return RobustBox(points, 0.005, 0.0).diagonal().norm();
}

TEST(IdentityRule, RenumberedPointsInAnotherGaugeKeepParallelLines) {
  const Model v1 = MakeModel(kKey, 500);
  const IdentityResult r1 = AssignDirections(kKey, v1.Input(), {}, {});
  EXPECT_EQ(r1.fresh + r1.from_same_place, 500u);
  const ReleaseLedger ledger = Release(v1, r1);
  // Version 2: ids offset, every point and camera moved by a similarity.
  const Sim3d t(0.5,
                Eigen::Quaterniond(Eigen::AngleAxisd(1.1, Eigen::Vector3d(0, 1, 1).normalized())),
                Eigen::Vector3d(3, 4, 5));
  Model v2 = MakeModel(kKey, 500, 1000);
  for (auto& x : v2.points) x = t * x;
  for (auto& [h, c] : v2.images) c = t * c;
  const IdentityResult r2 = AssignDirections(kKey, v2.Input(), ledger, {});
  EXPECT_EQ(r2.from_observations, 500u);
  EXPECT_LT(r2.misalignment, 1e-12);
  const Eigen::Matrix3d rotation = t.rotation.toRotationMatrix();
  for (size_t i = 0; i < 500; ++i) {
    // In the first version's frame the new direction is the released one.
    EXPECT_LT((rotation.transpose() * r2.directions[i]).cross(r1.directions[i]).norm(), 1e-12) << i;
  }
}

TEST(IdentityRule, AMergeOfTwoReleasedPointsIsLeftOutAndAMisalignedVersionRefused) {
  const Model v1 = MakeModel(kKey, 200);
  const IdentityResult r1 = AssignDirections(kKey, v1.Input(), {}, {});
  const ReleaseLedger ledger = Release(v1, r1);
  // Point 0 of version 2 holds point 0's and point 1's observations.
  Model v2 = v1;
  v2.observations[v2.start[0] + 1] = v1.observations[v1.start[1]];
  const IdentityResult r2 = AssignDirections(kKey, v2.Input(), ledger, {});
  ASSERT_GT(r1.directions[0].cross(r1.directions[1]).norm(), 1e-9);
  EXPECT_EQ(r2.left_out, 1u);
  EXPECT_FALSE(r2.keep[0]);
  EXPECT_EQ(r2.from_observations, 199u);
  // Points moved far from their released lines without the cameras moving:
  // the versions cannot be aligned; refused, naming why.
  Model v3 = v1;
  for (auto& x : v3.points) x = -x + Eigen::Vector3d(7, 0, 0);
  try {
    AssignDirections(kKey, v3.Input(), ledger, {});
    FAIL() << "a misaligned version was lifted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot be aligned"), std::string::npos) << e.what();
  }
}

// Every image renamed and its features extracted again: nothing ties the
// version to the released one (no shared image to align through, no
// observation to check against): refused.
TEST(IdentityRule, AVersionSharingNoImageWithTheReleasedOneIsRefused) {
  const Model v1 = MakeModel(kKey, 100);
  const ReleaseLedger ledger = Release(v1, AssignDirections(kKey, v1.Input(), {}, {}));
  const Model renamed = MakeModel(kKey, 100, 1, "renamed", 50);
  try {
    AssignDirections(kKey, renamed.Input(), ledger, {});
    FAIL() << "a version sharing nothing with the released one was lifted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("shares 0 images and 0 observations"), std::string::npos)
        << e.what();
  }
}

// Images renamed and points renumbered, the same features: the observations
// still name the released points.
TEST(IdentityRule, RenamedImagesWithTheSameFeaturesKeepTheirLines) {
  const Model v1 = MakeModel(kKey, 100);
  const IdentityResult r1 = AssignDirections(kKey, v1.Input(), {}, {});
  const ReleaseLedger ledger = Release(v1, r1);
  const Model renamed = MakeModel(kKey, 100, 5000, "renamed");
  const IdentityResult r2 = AssignDirections(kKey, renamed.Input(), ledger, {});
  EXPECT_EQ(r2.from_observations, 100u);
  for (size_t i = 0; i < 100; ++i) EXPECT_EQ(r2.directions[i], r1.directions[i]) << i;
}

TEST(IdentityRule, PointsAtOnePlaceShareADirectionWithoutChains) {
  Model m = MakeModel(kKey, 100);
  // A chain of points 0.6 eps apart along x, from point 0.
  const double eps = 1e-3 * RobustBoxDiagonalForTest(m.points);
  for (int k = 1; k <= 5; ++k) m.points[k] = m.points[0] + Eigen::Vector3d(0.6 * eps * k, 0, 0);
  const IdentityResult r = AssignDirections(kKey, m.Input(), {}, {});
  // Every point within eps of a seed shares its direction; none copies a copy.
  size_t parallel_to_0 = 0;
  for (int k = 1; k <= 5; ++k)
    parallel_to_0 += r.directions[k].cross(r.directions[0]).norm() < 1e-12;
  EXPECT_GE(parallel_to_0, 1u);
  EXPECT_LE(parallel_to_0, 2u);
  // No chains: points with one direction lie within 2 eps (a bundle around its seed).
  for (int a = 0; a <= 5; ++a) {
    for (int b = a + 1; b <= 5; ++b) {
      if (r.directions[a].cross(r.directions[b]).norm() < 1e-12) {
        EXPECT_LE((m.points[a] - m.points[b]).norm(), 2 * eps * (1 + 1e-9)) << a << " " << b;
      }
    }
  }
}

TEST(IdentityRule, ALedgerIsReadBackAndADamagedOneIsAnError) {
  testing::TempDir tmp;
  const Model m = MakeModel(kKey, 50);
  const ReleaseLedger ledger = Release(m, AssignDirections(kKey, m.Input(), {}, {}));
  WriteLedger(tmp.Path("a.ledger"), ledger);
  const ReleaseLedger back = ReadLedger(tmp.Path("a.ledger"));
  ASSERT_EQ(back.lines.size(), ledger.lines.size());
  EXPECT_EQ(back.observations, ledger.observations);
  for (size_t i = 0; i < back.lines.size(); ++i) EXPECT_EQ(back.lines[i].w, ledger.lines[i].w);
  EXPECT_EQ(back.sketch, ledger.sketch);
  EXPECT_EQ(back.diagonal, ledger.diagonal);
  EXPECT_GT(back.diagonal, 0);
  EXPECT_EQ(back.sketch, m.sketches);
  EXPECT_TRUE(ReadLedger(tmp.Path("absent.ledger")).empty());
  std::string bytes = ReadFileToString(tmp.Path("a.ledger"));
  bytes[bytes.size() / 2] ^= 1;
  WriteFileAtomically(tmp.Path("b.ledger"), [&](std::ostream& os) { os << bytes; });
  EXPECT_THROW(ReadLedger(tmp.Path("b.ledger")), Error);
  // Counts claiming more than the file holds: refused before reading.
  bytes = ReadFileToString(tmp.Path("a.ledger"));
  bytes[std::string("linecloud-release-ledger 2\n").size() + 7] = 0x7f;
  WriteFileAtomically(tmp.Path("c.ledger"), [&](std::ostream& os) { os << bytes; });
  try {
    ReadLedger(tmp.Path("c.ledger"));
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("corrupt release ledger"), std::string::npos) << e.what();
  }
}

// [rebuild] A version whose features were extracted again (another SIFT
// setting): the same photos (names), no shared observation, the points
// re-triangulated with noise, renumbered, in another gauge. Each point finds
// its own released line by place through the images' alignment (its sketch
// picks it among the lines passing near it) and takes the released line
// itself: the version publishes no line that crosses a released one.
Model Rebuilt(const Model& v1, const Sim3d& gauge, double noise, uint64_t first_id) {
  Model v2 = MakeModel(kKey, v1.ids.size(), first_id, "img", 50);  // other features
  std::mt19937_64 rng(11);
  std::normal_distribution<double> g(0, noise);
  std::uniform_int_distribution<int> bit(0, 63);
  for (size_t k = 0; k < v2.points.size(); ++k) {
    v2.points[k] = gauge * (v1.points[k] + Eigen::Vector3d(g(rng), g(rng), g(rng)));
    v2.sketches[k] = v1.sketches[k] ^ (uint64_t{1} << bit(rng)) ^ (uint64_t{1} << bit(rng));
  }
  for (auto& [h, c] : v2.images) c = gauge * c;
  return v2;
}

TEST(IdentityRule, AVersionWithFeaturesExtractedAgainTakesItsReleasedLines) {
  const Model v1 = MakeModel(kKey, 3000);
  const IdentityResult r1 = AssignDirections(kKey, v1.Input(), {}, {});
  const ReleaseLedger ledger = Release(v1, r1);
  const Sim3d gauge(2.0, Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ())),
                    Eigen::Vector3d(1, -2, 3));
  const double diagonal = RobustBoxDiagonalForTest(v1.points);
  const Model v2 = Rebuilt(v1, gauge, 1e-4 * diagonal, 90000);
  IdentityOptions o;
  o.same_place = 3e-3;
  const IdentityResult r2 = AssignDirections(kKey, v2.Input(), ledger, o);
  EXPECT_EQ(r2.from_observations, 0u);
  EXPECT_EQ(r2.shared_images, 10u);
  EXPECT_EQ(r2.from_released_place, 3000u);
  EXPECT_EQ(r2.on_released_line, 3000u);
  EXPECT_GT(r2.released_place_close, 10 * std::max<size_t>(r2.released_place_close_by_chance, 1));
  size_t own = 0;
  for (size_t k = 0; k < 3000; ++k) {
    own += r2.ledger_line[k] == static_cast<int64_t>(k);
    // The published line is the released line, moved into this gauge.
    const PluckerLine released = Transform(gauge, ledger.lines[r2.ledger_line[k]]);
    EXPECT_LT(released.DistanceTo(r2.anchors[k]), 1e-9 * diagonal) << k;
    EXPECT_LT(released.v.cross(r2.directions[k]).norm(), 1e-9) << k;
  }
  EXPECT_EQ(own, 3000u);
  // Without sketches (a lift without descriptors) the nearest line is taken.
  Model bare = v2;
  bare.sketches.clear();
  EXPECT_EQ(AssignDirections(kKey, bare.Input(), ledger, o).from_released_place, 3000u);
}

// A piece of the scene rebuilt and lifted on its own (the owner re-releases
// it tile by tile): its same_place is the released scene's, not the piece's
// (an outsider's tiles of a fountain-P11 rebuild published 1.1-1.6 % of the
// points within 1e-3 beyond the density attack when it was the piece's).
TEST(IdentityRule, APieceOfTheSceneKeepsTheScenesSamePlace) {
  const Model v1 = MakeModel(kKey, 3000);
  const ReleaseLedger ledger = Release(v1, AssignDirections(kKey, v1.Input(), {}, {}));
  const double diagonal = RobustBoxDiagonalForTest(v1.points);
  const Model all = Rebuilt(v1, Sim3d(), 0, 90000);
  Model tile;
  tile.images = all.images;
  std::vector<size_t> rows;
  std::mt19937_64 rng(9);
  std::normal_distribution<double> g(0, 1.2e-3 * diagonal / std::sqrt(3.0));
  for (size_t k = 0; k < all.ids.size(); ++k) {
    if (all.points[k].cwiseAbs().maxCoeff() > 1.5) continue;  // a cube of 3 in a box of 10
    rows.push_back(k);
    tile.ids.push_back(all.ids[k]);
    // Half the points re-triangulated ~1e-3 of the scene away from their released ones.
    const bool far = rows.size() % 2 == 0;
    tile.points.push_back(
        all.points[k] + (far ? Eigen::Vector3d(g(rng), g(rng), g(rng)) : Eigen::Vector3d::Zero()));
    tile.sketches.push_back(all.sketches[k]);
    tile.start.push_back(static_cast<uint32_t>(tile.observations.size()));
    for (uint32_t o = all.start[k]; o < all.start[k + 1]; ++o) {
      tile.observations.push_back(all.observations[o]);
    }
  }
  tile.start.push_back(static_cast<uint32_t>(tile.observations.size()));
  ASSERT_GT(rows.size(), 50u);
  const IdentityResult r = AssignDirections(kKey, tile.Input(), ledger, {});
  EXPECT_NEAR(r.diagonal, ledger.diagonal, 1e-9 * diagonal);
  size_t own = 0;
  for (size_t k = 0; k < rows.size(); ++k) own += r.ledger_line[k] == static_cast<int64_t>(rows[k]);
  EXPECT_EQ(own, rows.size());
}

// The outsider's case: two points 2 same_place apart were released with
// different lines; the rebuild moved them within same_place of each other.
// Each must keep its own released line — copying its neighbour's direction
// would cross its own released line next to it.
TEST(IdentityRule, APointsOwnReleasedLineComesBeforeANeighboursDirection) {
  Model v1 = MakeModel(kKey, 400);
  const double eps = 1e-3 * RobustBoxDiagonalForTest(v1.points);
  const Eigen::Vector3d step(2 * eps, 0, 0);
  for (size_t k = 1; k < 200; k += 2) v1.points[k] = v1.points[k - 1] + step;
  const IdentityResult r1 = AssignDirections(kKey, v1.Input(), {}, {});
  const ReleaseLedger ledger = Release(v1, r1);
  Model v2 = Rebuilt(v1, Sim3d(), 0, 7000);
  for (size_t k = 1; k < 200; k += 2) {  // the other 200 stay: they verify the alignment
    v2.points[k - 1] += 0.6 * step / 2;
    v2.points[k] -= 0.6 * step / 2;
  }
  const IdentityResult r2 = AssignDirections(kKey, v2.Input(), ledger, {});
  size_t own = 0;
  for (size_t k = 0; k < 400; ++k) own += r2.ledger_line[k] == static_cast<int64_t>(k);
  EXPECT_EQ(own, 400u);
  EXPECT_EQ(r2.from_same_place, 0u);
}

// Two released lines pass near a rebuilt point: the nearer is another
// point's, the farther its own (its descriptor's sketch says so).
TEST(IdentityRule, TheSketchPicksAPointsOwnLineOverANearerOne) {
  const Model v1 = MakeModel(kKey, 200);
  ReleaseLedger ledger = Release(v1, AssignDirections(kKey, v1.Input(), {}, {}));
  const double diagonal = RobustBoxDiagonalForTest(v1.points);
  Model v2 = Rebuilt(v1, Sim3d(), 0, 5000);
  // Point 0 moved 2e-4 of the diagonal off its line, and a line of point 1's
  // sketch passing 1e-5 from it.
  const Eigen::Vector3d off = ledger.lines[0].v.unitOrthogonal();
  v2.points[0] = v1.points[0] + 2e-4 * diagonal * off;
  const Eigen::Vector3d v = Eigen::Vector3d(1, 2, 3).normalized();
  ledger.lines.push_back(
      PluckerLine::FromPointAndDirection(v2.points[0] + 1e-5 * diagonal * v.unitOrthogonal(), v));
  ledger.compact.push_back(0);
  ledger.sketch.push_back(v1.sketches[1]);
  const IdentityResult r = AssignDirections(kKey, v2.Input(), ledger, {});
  EXPECT_EQ(r.ledger_line[0], 0);
  v2.sketches.clear();
  EXPECT_EQ(AssignDirections(kKey, v2.Input(), ledger, {}).ledger_line[0], 200);
}

// The same photos but a reconstruction that does not fit the released one
// (its points scrambled): no observation and no place verifies the
// alignment: refused, with the figures.
TEST(IdentityRule, ARebuiltVersionThatDoesNotFitIsRefused) {
  const Model v1 = MakeModel(kKey, 3000);
  const ReleaseLedger ledger = Release(v1, AssignDirections(kKey, v1.Input(), {}, {}));
  Model v2 = Rebuilt(v1, Sim3d(), 0, 90000);
  std::mt19937_64 rng(5);
  std::shuffle(v2.points.begin(), v2.points.end(), rng);
  for (auto& x : v2.points) x = Eigen::Vector3d(x.y(), x.z(), x.x()) * 0.9;
  try {
    AssignDirections(kKey, v2.Input(), ledger, {});
    FAIL() << "an unverified version was lifted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot be aligned with its released version"),
              std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("would by chance"), std::string::npos) << e.what();
  }
}

// A compact256 key's 256 directions cannot follow a rotation: a version in
// another gauge is refused, naming why.
TEST(IdentityRule, ACompactKeysVersionInAnotherGaugeIsRefused) {
  const LiftingKey compact(LiftingKey::Bytes{7, 1, 2, 3}, DirectionSet::kCompact256);
  const Model v1 = MakeModel(compact, 300);
  const ReleaseLedger ledger = Release(v1, AssignDirections(compact, v1.Input(), {}, {}));
  const Sim3d gauge(1.0, Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX())),
                    Eigen::Vector3d::Zero());
  Model v2 = MakeModel(compact, 300, 500);
  for (auto& x : v2.points) x = gauge * x;
  for (auto& [h, c] : v2.images) c = gauge * c;
  try {
    AssignDirections(compact, v2.Input(), ledger, {});
    FAIL() << "a rotated version of a compact256 key was lifted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("compact256"), std::string::npos) << e.what();
  }
}

TEST(DescriptorSketch, HammingDistanceFollowsTheAngle) {
  const DescriptorSketcher sketcher(kKey, 128);
  std::mt19937_64 rng(2);
  std::uniform_int_distribution<int> byte(0, 255);
  std::vector<uint8_t> a(128), b(128), c(128);
  double near_bits = 0, far_bits = 0;
  for (int t = 0; t < 50; ++t) {
    for (int k = 0; k < 128; ++k) {
      a[k] = static_cast<uint8_t>(byte(rng) / 2);
      b[k] = static_cast<uint8_t>(std::clamp(a[k] + byte(rng) / 16 - 8, 0, 255));  // a match
      c[k] = static_cast<uint8_t>(byte(rng) / 2);                                  // unrelated
    }
    near_bits += SketchDistance(sketcher.Sketch(a), sketcher.Sketch(b));
    far_bits += SketchDistance(sketcher.Sketch(a), sketcher.Sketch(c));
  }
  EXPECT_LT(near_bits / 50, 8);
  EXPECT_GT(far_bits / 50, 2 * near_bits / 50);
  EXPECT_EQ(sketcher.Sketch(a), DescriptorSketcher(kKey, 128).Sketch(a));  // keyed, fixed
  EXPECT_NE(sketcher.Sketch(a),
            DescriptorSketcher(LiftingKey(LiftingKey::Bytes{9}), 128).Sketch(a));
  EXPECT_EQ(SketchDistance(0, sketcher.Sketch(a)), 64);
}

}  // namespace
}  // namespace linecloud
