// Every implemented minimal solver on 10 000 seeded random instances (random
// line signs, rotations about y for +u, scales in [0.1, 10] for Sim3, random
// rig layouts for m-): the true pose must be among the solutions in >= 99.9%
// of them, and every returned solution must satisfy the method's equations.
#include <iostream>
#include <random>

#include <set>
#include <string_view>

#include <gtest/gtest.h>

#include "linecloud/solvers/m_p4l_l.h"
#include "linecloud/solvers/m_p4l_u.h"
#include "linecloud/solvers/minimal_problem.h"
#include "linecloud/solvers/p3p.h"
#include "linecloud/solvers/p6l.h"
#include "linecloud/synthetic/minimal_instances.h"
#include "linecloud/testing/test_util.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

class MinimalSolverTest : public ::testing::TestWithParam<std::string_view> {};

TEST_P(MinimalSolverTest, RecoversTheTruePoseAndSatisfiesItsEquations) {
  const MethodInfo& method = FindMethod(GetParam());
  std::mt19937_64 rng(1234);
  const int kInstances = testing::InstanceCount(10000);
  int found = 0;
  size_t total_solutions = 0;
  double worst_residual = 0;
  std::vector<Sim3d> solutions;
  for (int k = 0; k < kInstances; ++k) {
    MinimalInstance inst = RandomMinimalInstance(method, rng);
    // Lines have no orientation: flip half of them.
    for (PluckerLine& l : inst.sample.lines) {
      if (rng() & 1) l = PluckerLine(-l.v, -l.w);
    }
    CheckSample(method, inst.sample, "test");
    SolveMinimal(method, inst.sample, &solutions);
    total_solutions += solutions.size();
    bool has_truth = false;
    for (const Sim3d& s : solutions) {
      ASSERT_TRUE(s.rotation.coeffs().allFinite() && s.translation.allFinite() &&
                  std::isfinite(s.scale));
      worst_residual = std::max(worst_residual, MaxResidual(method, inst.sample, s));
      const PoseError e = ComparePoses(s, inst.truth);
      has_truth |= e.rotation_rad < 1e-6 && e.translation_rel < 1e-6 && e.scale_rel < 1e-6;
    }
    found += has_truth;
  }
  std::cout << "[ " << method.name << " ] true pose in " << found << " / " << kInstances
            << ", mean solutions " << double(total_solutions) / kInstances << ", worst residual "
            << worst_residual << "\n";
  EXPECT_GE(found, kInstances * 999 / 1000)
      << method.name << ": true pose found in " << found << " of " << kInstances;
  EXPECT_LT(worst_residual, 1e-8) << method.name;
  EXPECT_GT(total_solutions, 0u);
}

// p3P with the three points seen in a 10° field of view (a telephoto lens, or
// three nearby points far away): the conics are nearly tangent, the cubic
// nearly has a double root — the true pose must still come out.
TEST(P3P, RecoversTheTruePoseInANarrowFieldOfView) {
  const MethodInfo& method = FindMethod("p3P");
  std::mt19937_64 rng(99);
  const int kInstances = testing::InstanceCount(10000);
  int found = 0;
  double worst_residual = 0;
  std::vector<Sim3d> solutions;
  for (int k = 0; k < kInstances; ++k) {
    const MinimalInstance inst = RandomMinimalInstance(method, rng, InstanceFamily::kNarrowFov);
    SolveMinimal(method, inst.sample, &solutions);
    bool has_truth = false;
    for (const Sim3d& s : solutions) {
      worst_residual = std::max(worst_residual, MaxResidual(method, inst.sample, s));
      const PoseError e = ComparePoses(s, inst.truth);
      has_truth |= e.rotation_rad < 1e-6 && e.translation_rel < 1e-6;
    }
    found += has_truth;
  }
  std::cout << "[ p3P, 10° FOV ] true pose in " << found << " / " << kInstances
            << ", worst residual " << worst_residual << "\n";
  EXPECT_GE(found, kInstances * 999 / 1000);
  EXPECT_LT(worst_residual, 1e-8);
}

// Degenerate and invalid samples give no solution or valid ones — never NaN.
TEST_P(MinimalSolverTest, DegenerateSamplesGiveFiniteOrNoSolutions) {
  const MethodInfo& method = FindMethod(GetParam());
  std::mt19937_64 rng(99);
  std::vector<Sim3d> solutions;
  for (int variant = 0; variant < 6; ++variant) {
    MinimalInstance inst = RandomMinimalInstance(method, rng);
    MinimalSample& s = inst.sample;
    auto& pts = method.local_points ? s.points_local : (method.lines ? s.bearings : s.points);
    switch (variant) {
      case 0:  // coincident points
        for (auto& p : pts) p = pts[0];
        if (!method.lines && !method.local_points) {
          for (auto& b : s.bearings) b = s.bearings[0];
        }
        break;
      case 1:  // collinear points
        for (size_t i = 0; i < pts.size(); ++i)
          pts[i] = pts[0] + double(i) * Eigen::Vector3d(1, 2, 3);
        break;
      case 2:  // parallel lines / identical directions
        for (auto& l : s.lines) l = PluckerLine::FromPointAndDirection(l.Anchor(), s.lines[0].v);
        for (auto& b : s.bearings) b = s.bearings[0];
        break;
      case 3:  // lines through the origin / camera centre
        for (auto& l : s.lines) l.w.setZero();
        break;
      case 4:  // zero vectors
        for (auto& p : pts) p.setZero();
        break;
      case 5:  // everything identical
        for (auto& p : s.points) p = Eigen::Vector3d(1, 1, 1);
        for (auto& p : s.points_local) p = Eigen::Vector3d(1, 1, 1);
        break;
    }
    try {
      CheckSample(method, s, "test");
    } catch (const Error&) {
      continue;  // rejected up front, with a message: fine
    }
    SolveMinimal(method, s, &solutions);
    for (const Sim3d& p : solutions) {
      EXPECT_TRUE(p.rotation.coeffs().allFinite() && p.translation.allFinite() &&
                  std::isfinite(p.scale) && p.scale > 0)
          << method.name << " variant " << variant;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Solvers, MinimalSolverTest,
                         ::testing::ValuesIn(testing::ImplementedMethodNames()),
                         testing::MethodTestName);

TEST(MinimalProblem, CheckSampleNamesTheField) {
  const MethodInfo& m = FindMethod("m-p2P+u");
  std::mt19937_64 rng(5);
  MinimalInstance inst = RandomMinimalInstance(m, rng);
  inst.sample.camera_index[1] = 7;
  try {
    CheckSample(m, inst.sample, "problem.json");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("camera_index"), std::string::npos) << e.what();
  }
  inst = RandomMinimalInstance(m, rng);
  inst.sample.points.pop_back();
  EXPECT_THROW(CheckSample(m, inst.sample, "problem.json"), Error);
  inst = RandomMinimalInstance(m, rng);
  inst.sample.points[0].x() = std::nan("");
  EXPECT_THROW(CheckSample(m, inst.sample, "problem.json"), Error);
  EXPECT_THROW(FindMethod("p5P"), Error);
}

// [rigs] The method a query implies, by the paper's names: every combination
// of map, cameras, local points, their scale and gravity names one method,
// and each of the 16 is reached.
TEST(MinimalProblem, MethodForNamesTheMethodThatUsesWhatTheQueryBrings) {
  EXPECT_EQ(MethodFor({}).name, "p6L");
  EXPECT_EQ(MethodFor({.gravity = true}).name, "p4L+u");
  EXPECT_EQ(MethodFor({.several_cameras = true}).name, "m-p6L");
  EXPECT_EQ(MethodFor({.several_cameras = true, .gravity = true}).name, "m-p4L+u");
  EXPECT_EQ(MethodFor({.local_points = true}).name, "m-P4L+l");  // one camera: a rig of one
  EXPECT_EQ(MethodFor({.local_points = true, .known_scale = true}).name, "m-P3L+l+s");
  EXPECT_EQ(MethodFor({.local_points = true, .gravity = true}).name, "m-P3L+l+u");
  EXPECT_EQ(MethodFor({.local_points = true, .known_scale = true, .gravity = true}).name,
            "m-P2L+l+u+s");
  EXPECT_EQ(MethodFor({.known_scale = true}).name, "p6L");  // a scale without points: nothing
  EXPECT_EQ(MethodFor({.lines = false, .several_cameras = true, .local_points = true}).name,
            "m-P3P+l");
  std::set<std::string_view> reached;
  for (const bool lines : {false, true}) {
    for (int bits = 0; bits < 16; ++bits) {
      reached.insert(MethodFor({.lines = lines,
                                .several_cameras = (bits & 1) != 0,
                                .local_points = (bits & 2) != 0,
                                .known_scale = (bits & 4) != 0,
                                .gravity = (bits & 8) != 0})
                         .name);
    }
  }
  EXPECT_EQ(reached.size(), AllMethods().size());
}

}  // namespace
}  // namespace linecloud

namespace linecloud {
namespace {

// [harden] 7: a public solver given too short a sample (or no output) throws
// instead of reading past its spans.
TEST(Solvers, PreconditionsAtTheEntryPoints) {
  const std::vector<Eigen::Vector3d> two(2, Eigen::Vector3d(0, 0, 1)),
      five(5, Eigen::Vector3d(0, 0, 1));
  const std::vector<PluckerLine> lines5(
      5, PluckerLine(Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 1, 0)));
  std::vector<Rigid3d> out;
  EXPECT_THROW(p3p(two, two, &out), Error);
  EXPECT_THROW(p6l(five, lines5, &out), Error);
  EXPECT_THROW(p4l_u(two, lines5, &out), Error);
  EXPECT_THROW(p3p(std::vector<Eigen::Vector3d>(3, Eigen::Vector3d(0, 0, 1)),
                   std::vector<Eigen::Vector3d>(3, Eigen::Vector3d(0, 0, 1)), nullptr),
               Error);
  std::vector<Sim3d> sims;
  EXPECT_THROW(m_p4l_l(std::span<const PluckerLine>(lines5.data(), 3), five, &sims), Error);
}

}  // namespace
}  // namespace linecloud
