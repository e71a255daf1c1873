// The p6L / m-p6L minimal solvers (solvers/p6l.h) on 256 fixed-seed noise-free
// instances: camera within 1–3 units of a unit cube of points, lines through
// them in random directions. Time per call; run with
// --benchmark_repetitions=N --benchmark_report_aggregates_only=true and read
// the minimum to compare builds on a shared machine (e.g. the code before and
// after a change, built side by side).
#include <array>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <benchmark/benchmark.h>

#include "linecloud/geometry/plucker.h"
#include "linecloud/geometry/rigid3.h"
#include "linecloud/solvers/p6l.h"

namespace linecloud {
namespace {

struct P6lInstance {
  std::array<Eigen::Vector3d, 6> origins, bearings;
  std::array<PluckerLine, 6> lines;
};

// origins_spread 0: one central camera (p6L); > 0: six rays from a rig.
std::vector<P6lInstance> P6lInstances(double origins_spread) {
  std::mt19937_64 rng(6);
  std::normal_distribution<double> g;
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<P6lInstance> out(256);
  for (P6lInstance& instance : out) {
    const Eigen::Quaterniond q = Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized();
    const Eigen::Vector3d t(u(rng), u(rng), 2 + u(rng));
    for (int i = 0; i < 6; ++i) {
      const Eigen::Vector3d point(u(rng), u(rng), u(rng));
      instance.lines[i] =
          PluckerLine::FromPointAndDirection(point, Eigen::Vector3d(g(rng), g(rng), g(rng)));
      instance.origins[i] = origins_spread * Eigen::Vector3d(u(rng), u(rng), u(rng));
      instance.bearings[i] = (q * point + t - instance.origins[i]).normalized();
    }
  }
  return out;
}

void BM_P6l(benchmark::State& state) {
  const std::vector<P6lInstance> instances = P6lInstances(0);
  std::vector<Rigid3d> poses;
  size_t i = 0;
  for (auto _ : state) {
    const P6lInstance& s = instances[i++ % instances.size()];
    benchmark::DoNotOptimize(p6l(s.bearings, s.lines, &poses));
  }
}
BENCHMARK(BM_P6l);

void BM_MP6l(benchmark::State& state) {
  const std::vector<P6lInstance> instances = P6lInstances(0.3);
  std::vector<Rigid3d> poses;
  size_t i = 0;
  for (auto _ : state) {
    const P6lInstance& s = instances[i++ % instances.size()];
    benchmark::DoNotOptimize(m_p6l(s.origins, s.bearings, s.lines, &poses));
  }
}
BENCHMARK(BM_MP6l);

}  // namespace
}  // namespace linecloud
