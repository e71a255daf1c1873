#include "linecloud/benchmarks/solver_bench.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>

#include <Eigen/Geometry>

#include "linecloud/util/statistics.h"
#include "linecloud/synthetic/minimal_instances.h"
#include "linecloud/util/error.h"

namespace linecloud {

void SolverBenchOptions::Check() const {
  if (instances < 10) Fail("bench: --instances must be >= 10");
  if (!(min_seconds > 0)) Fail("bench: --min-time must be > 0");
  for (const std::string& m : methods) FindMethod(m);
}

namespace {

Eigen::Matrix3Xd Columns(const std::vector<Eigen::Vector3d>& v) {
  Eigen::Matrix3Xd m(3, v.size());
  for (size_t i = 0; i < v.size(); ++i) m.col(i) = v[i];
  return m;
}

// Eigen's umeyama (SVD-based least squares): the peer of the point-point
// methods named in METHODS.md.
void UmeyamaPeer(const MinimalSample& s, bool with_scale, std::vector<Sim3d>* out) {
  const Eigen::Matrix4d t = Eigen::umeyama(Columns(s.points), Columns(s.points_local), with_scale);
  out->clear();
  const Eigen::Matrix3d sr = t.topLeftCorner<3, 3>();
  const double scale = with_scale ? std::cbrt(sr.determinant()) : 1.0;
  out->emplace_back(scale, Eigen::Quaterniond(sr / scale), t.topRightCorner<3, 1>());
}

// Whole sweeps of call(0 .. n − 1) until min_seconds have elapsed.
template <typename Call>
double MicrosecondsPerCall(size_t n, double min_seconds, const Call& call) {
  using Clock = std::chrono::steady_clock;
  size_t calls = 0;
  const auto start = Clock::now();
  double elapsed = 0;
  do {
    for (size_t i = 0; i < n; ++i) call(i);
    calls += n;
    elapsed = std::chrono::duration<double>(Clock::now() - start).count();
  } while (elapsed < min_seconds);
  return 1e6 * elapsed / calls;
}

template <typename Solve>
SolverBenchRow Measure(const std::string& method_name, const std::string& solver,
                       const std::vector<MinimalInstance>& instances, double min_seconds,
                       const Solve& solve) {
  SolverBenchRow row;
  row.method = method_name;
  row.solver = solver;
  row.instances = static_cast<int>(instances.size());
  std::vector<Sim3d> solutions;
  // Accuracy pass.
  size_t total = 0;
  int found = 0;
  std::vector<double> log_errors;
  for (const MinimalInstance& inst : instances) {
    solve(inst.sample, &solutions);
    total += solutions.size();
    double best = 1e300;
    bool has_truth = false;
    for (const Sim3d& s : solutions) {
      const PoseError e = ComparePoses(s, inst.truth);
      best = std::min(best, e.rotation_rad);
      has_truth |= e.rotation_rad < 1e-6 && e.translation_rel < 1e-6 && e.scale_rel < 1e-6;
    }
    found += has_truth;
    log_errors.push_back(std::log10(std::max(best, 1e-17)));
  }
  row.mean_solutions = static_cast<double>(total) / instances.size();
  row.found_percent = 100.0 * found / instances.size();
  row.median_log10_rotation_error = Median(std::move(log_errors));
  row.us_per_call = MicrosecondsPerCall(instances.size(), min_seconds,
                                        [&](size_t i) { solve(instances[i].sample, &solutions); });
  return row;
}

}  // namespace

std::vector<PeerSolver> AvailablePeers() {
  std::vector<PeerSolver> peers = {
      {"m-P3P+l", "eigen-umeyama",
       [](const MinimalSample& s, std::vector<Sim3d>* out) { UmeyamaPeer(s, true, out); }},
      {"m-P3P+l+s", "eigen-umeyama",
       [](const MinimalSample& s, std::vector<Sim3d>* out) { UmeyamaPeer(s, false, out); }},
  };
  const std::vector<PeerSolver> opengv = OpenGvPeers();
  peers.insert(peers.end(), opengv.begin(), opengv.end());
  return peers;
}

std::vector<SolverBenchRow> RunSolverBench(
    const SolverBenchOptions& options, const std::function<void(const std::string&)>& progress) {
  options.Check();
  const std::vector<PeerSolver> peers = AvailablePeers();
  std::vector<SolverBenchRow> rows;
  for (const MethodInfo& method : AllMethods()) {
    if (!options.methods.empty() && std::find(options.methods.begin(), options.methods.end(),
                                              method.name) == options.methods.end()) {
      continue;
    }
    if (!method.implemented) continue;
    // p6L / m-p6L are also characterised on near-degenerate families.
    std::vector<InstanceFamily> families = {InstanceFamily::kGeneric};
    if (method.lines && !method.local_points && method.sample_size == 6) {
      families.insert(families.end(), {InstanceFamily::kNarrowFov, InstanceFamily::kLinesAlongRays,
                                       InstanceFamily::kLinesThroughPoint});
    }
    const auto make_instances = [&](InstanceFamily family, int correspondences) {
      std::mt19937_64 rng(options.seed);
      std::vector<MinimalInstance> instances;
      for (int i = 0; i < options.instances; ++i) {
        instances.push_back(RandomMinimalInstance(method, rng, family, correspondences));
        for (PluckerLine& l : instances.back().sample.lines) {
          if (rng() & 1) l = PluckerLine(-l.v, -l.w);  // lines are unoriented
        }
      }
      return instances;
    };
    for (const InstanceFamily family : families) {
      const std::vector<MinimalInstance> instances = make_instances(family, 0);
      const std::string name =
          family == InstanceFamily::kGeneric
              ? std::string(method.name)
              : std::string(method.name) + " [" + std::string(FamilyName(family)) + "]";
      progress(name);
      SolverBenchRow row = Measure(
          name, "linecloud", instances, options.min_seconds,
          [&](const MinimalSample& s, std::vector<Sim3d>* out) { SolveMinimal(method, s, out); });
      // The solver alone, on inputs prepared before timing (as PoseLib's
      // benchmark times its solvers); the call through SolveMinimal above,
      // which RANSAC makes, is kept as the API time.
      row.api_us_per_call = row.us_per_call;
      std::vector<PreparedSample> prepared;
      prepared.reserve(instances.size());
      for (const MinimalInstance& inst : instances) prepared.emplace_back(method, inst.sample);
      std::vector<Rigid3d> rigid;
      std::vector<Sim3d> sim;
      row.us_per_call = MicrosecondsPerCall(prepared.size(), options.min_seconds,
                                            [&](size_t i) { prepared[i].Solve(&rigid, &sim); });
      rows.push_back(std::move(row));
      for (const PeerSolver& peer : peers) {
        if (peer.method != method.name) continue;
        progress(name + " / " + peer.name);
        rows.push_back(Measure(
            name, peer.name,
            peer.correspondences > 0 ? make_instances(family, peer.correspondences) : instances,
            options.min_seconds, peer.solve));
      }
    }
  }
  return rows;
}

nlohmann::json SolverBenchRow::ToJson() const {
  nlohmann::json row = {{"method", method},
                        {"solver", solver},
                        {"us_per_call", us_per_call},
                        {"mean_solutions", mean_solutions},
                        {"found_percent", found_percent},
                        {"median_log10_rotation_error", median_log10_rotation_error},
                        {"instances", instances}};
  if (api_us_per_call > 0) row["api_us_per_call"] = api_us_per_call;
  return row;
}

}  // namespace linecloud
