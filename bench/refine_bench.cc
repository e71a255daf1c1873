// Our LM (estimation/refine_pose.h) against Ceres on the same refinement:
// one image, 350 inlier correspondences with 1 px noise, a start 0.05° /
// 2 cm off, Cauchy loss with scale 1 px, LM, at most 30 iterations, relative
// function tolerance 1e-6, one thread. The final costs are reported beside
// the times (Ceres' cost is ½ Σρ, ours Σρ; both shown as Σρ).
#include <random>

#include <benchmark/benchmark.h>

#include "linecloud/estimation/refine_pose.h"
#include "linecloud/synthetic/random.h"

#ifdef LINECLOUD_WITH_CERES
#include <ceres/ceres.h>
#include <ceres/rotation.h>
#endif

namespace linecloud {
namespace {

struct RefineProblem {
  PoseData data;
  std::vector<int> indices;
  Sim3d truth;
  Sim3d start;
};

RefineProblem MakeProblem(bool lines) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, 1.0);
  RefineProblem p;
  p.truth = Sim3d(1.0, RandomRotation(rng), Eigen::Vector3d(0.3, -0.2, 1.0));
  const Sim3d world_from_cam = p.truth.Inverse();
  constexpr double kFocal = 600;
  p.data.cam_from_rig.push_back(Rigid3d());
  for (int i = 0; i < 350; ++i) {
    const Eigen::Vector3d x_cam =
        Eigen::Vector3d(u(rng), 0.75 * u(rng), 1.0) * (2.0 + 8.0 * (0.5 + 0.5 * u(rng)));
    const Eigen::Vector3d x = world_from_cam * x_cam;
    const Eigen::Vector2d observed =
        x_cam.head<2>() / x_cam.z() + Eigen::Vector2d(noise(rng), noise(rng)) / kFocal;
    p.data.camera.push_back(0);
    p.data.normalized.push_back(observed);
    p.data.focal.push_back(kFocal);
    p.data.bearings.push_back(observed.homogeneous().normalized());
    if (lines) {
      p.data.lines.push_back(PluckerLine::FromPointAndDirection(x, RandomUnit(rng)));
    } else {
      p.data.points.push_back(x);
    }
    p.indices.push_back(i);
  }
  Eigen::Matrix<double, 7, 1> offset;
  offset << 0.0005, -0.0006, 0.0004, 0.02, -0.01, 0.015, 0.0;
  p.start = PerturbPose(p.truth, offset);
  return p;
}

void BM_RefineOwnLM(benchmark::State& state) {
  const RefineProblem p = MakeProblem(state.range(0) == 1);
  RefineOptions options;  // Cauchy 1 px, 30 iterations, tolerance 1e-6
  RefineSummary summary;
  for (auto _ : state) {
    Sim3d pose = p.start;
    summary = RefinePose(p.data, p.indices, options, &pose);
    benchmark::DoNotOptimize(pose);
  }
  state.counters["final_cost"] = summary.final_cost;
  state.counters["iterations"] = summary.iterations;
  state.SetLabel(state.range(0) == 1 ? "lines, eq. 6" : "points, eq. 2");
}
BENCHMARK(BM_RefineOwnLM)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

#ifdef LINECLOUD_WITH_CERES
// The same residuals, automatic derivatives, quaternion manifold.
struct PointResidual {
  Eigen::Vector2d x;
  Eigen::Vector3d point;
  double f;
  template <typename T>
  bool operator()(const T* q, const T* t, T* r) const {
    const Eigen::Map<const Eigen::Quaternion<T>> rotation(q);
    const Eigen::Matrix<T, 3, 1> p =
        rotation * point.cast<T>() + Eigen::Map<const Eigen::Matrix<T, 3, 1>>(t);
    r[0] = f * (p.x() / p.z() - x.x());
    r[1] = f * (p.y() / p.z() - x.y());
    return true;
  }
};
struct LineResidual {
  Eigen::Vector2d x;
  Eigen::Vector3d v, w;
  double f;
  template <typename T>
  bool operator()(const T* q, const T* t, T* r) const {
    const Eigen::Map<const Eigen::Quaternion<T>> rotation(q);
    const Eigen::Matrix<T, 3, 1> rv = rotation * v.cast<T>();
    const Eigen::Matrix<T, 3, 1> wc =
        rotation * w.cast<T>() + Eigen::Map<const Eigen::Matrix<T, 3, 1>>(t).cross(rv);
    r[0] = f * (wc.x() * x.x() + wc.y() * x.y() + wc.z()) /
           ceres::sqrt(wc.x() * wc.x() + wc.y() * wc.y());
    return true;
  }
};

void BM_RefineCeres(benchmark::State& state) {
  const bool lines = state.range(0) == 1;
  const RefineProblem p = MakeProblem(lines);
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  options.max_num_iterations = 30;
  options.function_tolerance = 1e-6;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  for (auto _ : state) {
    Eigen::Quaterniond q = p.start.rotation;
    Eigen::Vector3d t = p.start.translation;
    ceres::Problem::Options problem_options;
    problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(problem_options);
    ceres::CauchyLoss loss(1.0);
    for (const int i : p.indices) {
      if (lines) {
        problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<LineResidual, 1, 4, 3>(new LineResidual{
                p.data.normalized[i], p.data.lines[i].v, p.data.lines[i].w, p.data.focal[i]}),
            &loss, q.coeffs().data(), t.data());
      } else {
        problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<PointResidual, 2, 4, 3>(
                new PointResidual{p.data.normalized[i], p.data.points[i], p.data.focal[i]}),
            &loss, q.coeffs().data(), t.data());
      }
    }
    problem.SetManifold(q.coeffs().data(), new ceres::EigenQuaternionManifold);
    ceres::Solve(options, &problem, &summary);
    benchmark::DoNotOptimize(q);
  }
  state.counters["final_cost"] = 2 * summary.final_cost;
  state.counters["iterations"] = static_cast<double>(summary.iterations.size());
  state.SetLabel(lines ? "lines, eq. 6" : "points, eq. 2");
}
BENCHMARK(BM_RefineCeres)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);
#endif

}  // namespace
}  // namespace linecloud
