// estimate_pose (PoseLib's calling convention: 2D points, 3D lines or points,
// a camera, RANSAC and refinement options → pose, info), solve (one minimal
// solver, every solution) and methods (the 16 methods of Speciale et al.).
#include <algorithm>
#include <chrono>

#include <fmt/format.h>
#include <pybind11/stl.h>

#include "linecloud/io/json_util.h"
#include "linecloud/io/problem_json.h"
#include "linecloud/localize/localize.h"
#include "linecloud/python/bindings.h"
#include "linecloud/python/convert.h"
#include "linecloud/solvers/minimal_problem.h"
#include "linecloud/util/error.h"

namespace linecloud::python {
namespace {

constexpr const char* kEstimate = "estimate_pose";

// Everything one Localize call takes, built from the Python arguments.
struct Estimate {
  const MethodInfo* method = nullptr;
  Query query;
  LocalizationMap map;
  LocalizeOptions options;
};

void SetRansac(const nlohmann::json& o, RansacOptions* r) {
  const std::string where = std::string(kEstimate) + ": ransac";
  CheckKeys(o,
            {"max_error", "max_reproj_error", "confidence", "success_prob", "min_iterations",
             "max_iterations", "seed", "max_seconds", "local_optimization"},
            where);
  // PoseLib's names are accepted beside ours.
  for (const char* key : {"max_error", "max_reproj_error"}) {
    if (auto v = NumberOption(o, key, where)) r->max_error = *v;
  }
  for (const char* key : {"confidence", "success_prob"}) {
    if (auto v = NumberOption(o, key, where)) r->confidence = *v;
  }
  auto iterations = [&](const char* key, int* out) {
    if (auto v = IntegerOption(o, key, where)) {
      if (*v < 0 || *v > 100'000'000) Fail("{}: {} must be in [0, 1e8], got {}", where, key, *v);
      *out = static_cast<int>(*v);
    }
  };
  iterations("min_iterations", &r->min_iterations);
  iterations("max_iterations", &r->max_iterations);
  if (auto v = IntegerOption(o, "seed", where)) {
    if (*v < 0) Fail("{}: seed must be non-negative, got {}", where, *v);
    r->seed = static_cast<uint64_t>(*v);
  }
  if (auto v = NumberOption(o, "max_seconds", where)) r->max_seconds = *v;
  if (auto v = BoolOption(o, "local_optimization", where)) r->local_optimization = *v;
}

void SetRefine(py::handle refine, LocalizeOptions* options) {
  const std::string where = std::string(kEstimate) + ": refine";
  if (refine.is_none()) return;
  if (py::isinstance<py::bool_>(refine)) {
    options->refine = refine.cast<bool>();
    return;
  }
  const nlohmann::json o = ToJson(refine, where);
  CheckKeys(o, {"max_iterations", "loss_scale", "function_tolerance", "step_tolerance"}, where);
  RefineOptions& r = options->refinement;
  if (auto v = IntegerOption(o, "max_iterations", where)) {
    if (*v < 0 || *v > 1'000'000) Fail("{}: max_iterations must be in [0, 1e6], got {}", where, *v);
    r.max_iterations = static_cast<int>(*v);
  }
  if (auto v = NumberOption(o, "loss_scale", where)) r.loss_scale = *v;
  if (auto v = NumberOption(o, "function_tolerance", where)) r.function_tolerance = *v;
  if (auto v = NumberOption(o, "step_tolerance", where)) r.step_tolerance = *v;
}

void SetSuccess(py::handle success, LocalizeOptions* options) {
  const std::string where = std::string(kEstimate) + ": success";
  if (success.is_none()) return;
  if (py::isinstance<py::bool_>(success)) {
    // False: every pose RANSAC finds counts (PoseLib's behaviour).
    if (!success.cast<bool>()) options->success = SuccessCriteria::None();
    return;
  }
  const nlohmann::json o = ToJson(success, where);
  CheckKeys(o,
            {"min_inliers", "min_inlier_ratio", "max_rotation_uncertainty_deg",
             "max_focal_discrepancy", "max_principal_discrepancy", "max_position_uncertainty"},
            where);
  SuccessCriteria& s = options->success;
  if (auto v = IntegerOption(o, "min_inliers", where)) {
    if (*v < 0 || *v > 1 << 30) Fail("{}: min_inliers must be in [0, 2^30], got {}", where, *v);
    s.min_inliers_points = s.min_inliers_lines = static_cast<int>(*v);
  }
  if (auto v = NumberOption(o, "min_inlier_ratio", where)) s.min_inlier_ratio = *v;
  if (auto v = NumberOption(o, "max_rotation_uncertainty_deg", where)) {
    s.max_rotation_uncertainty_deg = *v;
  }
  if (auto v = NumberOption(o, "max_focal_discrepancy", where)) s.max_focal_discrepancy = *v;
  if (auto v = NumberOption(o, "max_principal_discrepancy", where)) {
    s.max_principal_discrepancy = *v;
  }
  if (auto v = NumberOption(o, "max_position_uncertainty", where)) {
    s.max_position_uncertainty = *v;
  }
}

// One camera's 2D points and lines or points, appended to the query and map.
void AddCorrespondences(const MethodInfo& method, int camera, py::handle points2D,
                        py::handle map_side, const std::string& suffix, Estimate* e) {
  size_t n = 0, m = 0;
  const std::vector<double> xy = FiniteRows(points2D, 2, "points2D" + suffix, &n);
  const int cols = method.lines ? 6 : 3;
  const std::vector<double> rows =
      FiniteRows(map_side, cols, (method.lines ? "lines" : "points3D") + suffix, &m);
  if (m != n) {
    Fail("{}: {} 2D points but {} {}{}", kEstimate, n, m, method.lines ? "lines" : "points3D",
         suffix);
  }
  for (size_t i = 0; i < n; ++i) {
    const uint64_t id = e->query.observations.size();
    QueryObservation o;
    o.camera = camera;
    o.xy = Eigen::Vector2d(xy[2 * i], xy[2 * i + 1]);
    o.id = id;
    e->query.observations.push_back(o);
    const double* r = rows.data() + cols * i;
    if (method.lines) {
      // The C++ entry points' check (LineCloud::Check): a direction and its
      // moment w = X x v. Any length of v is taken (the line is the same).
      Eigen::Vector3d v(r[0], r[1], r[2]), w(r[3], r[4], r[5]);
      const double length = v.norm();
      if (!(length > 0)) Fail("{}: lines{}[{}]: the direction v is zero", kEstimate, suffix, i);
      if (std::abs(length - 1) > 1e-12) {  // unit directions are taken bit for bit
        v /= length;
        w /= length;
      }
      if (!(std::abs(v.dot(w)) <= 1e-6 * std::max(1.0, w.norm()))) {
        Fail(
            "{}: lines{}[{}] is not a Pluecker line [v, w]: its moment w is not orthogonal to v "
            "(v.w / |v| = {:.3g}); give w = X x v for a point X on the line",
            kEstimate, suffix, i, v.dot(w));
      }
      std::get<LineMap>(e->map).lines[id] = PluckerLine(v, w);
    } else {
      std::get<PointMap>(e->map).points[id] = Eigen::Vector3d(r[0], r[1], r[2]);
    }
  }
}

Estimate MakeEstimate(const std::string& method_name, py::handle points2D, py::handle map_side,
                      py::handle camera, py::handle ransac, py::handle refine, py::handle success,
                      py::handle gravity, py::handle map_gravity, py::handle points_local,
                      py::handle cam_from_rig) {
  Estimate e;
  e.method = &FindMethod(method_name);
  const MethodInfo& method = *e.method;
  if (method.lines) {
    e.map = LineMap{};
  } else {
    e.map = PointMap{};
  }
  const bool lists = py::isinstance<py::list>(points2D) || py::isinstance<py::tuple>(points2D);
  if (lists && !method.multi) {
    Fail(
        "{}: {} takes one camera: points2D N x 2 and lines_or_points3D arrays, not lists (lists, "
        "one per camera, are for m- methods)",
        kEstimate, method.name);
  }
  if (lists) {
    const py::sequence p2 = py::reinterpret_borrow<py::sequence>(points2D);
    if (!py::isinstance<py::list>(map_side) && !py::isinstance<py::tuple>(map_side)) {
      throw py::type_error(std::string(kEstimate) + ": lines_or_points3D must be a list too");
    }
    if (!py::isinstance<py::list>(camera) && !py::isinstance<py::tuple>(camera)) {
      throw py::type_error(std::string(kEstimate) + ": camera must be a list of camera dicts too");
    }
    const py::sequence p3 = py::reinterpret_borrow<py::sequence>(map_side);
    const py::sequence cams = py::reinterpret_borrow<py::sequence>(camera);
    if (p3.size() != p2.size() || cams.size() != p2.size()) {
      Fail("{}: {} lists of 2D points, {} of 3D, {} cameras", kEstimate, p2.size(), p3.size(),
           cams.size());
    }
    for (size_t c = 0; c < p2.size(); ++c) {
      const std::string suffix = fmt::format("[{}]", c);
      e.query.cameras.push_back(CameraFromDict(cams[c], "camera" + suffix));
      AddCorrespondences(method, static_cast<int>(c), p2[c], p3[c], suffix, &e);
    }
  } else {
    e.query.cameras.push_back(CameraFromDict(camera, "camera"));
    AddCorrespondences(method, 0, points2D, map_side, "", &e);
  }
  if (!cam_from_rig.is_none()) {
    if (!py::isinstance<py::list>(cam_from_rig) && !py::isinstance<py::tuple>(cam_from_rig)) {
      throw py::type_error(std::string(kEstimate) + ": cam_from_rig must be a list of pose dicts");
    }
    size_t k = 0;
    for (py::handle pose : cam_from_rig) {
      e.query.cam_from_rig.push_back(PoseFromDict(pose, fmt::format("cam_from_rig[{}]", k++)));
    }
  }
  if (!points_local.is_none()) {
    size_t n = 0;
    const std::vector<double> x = FiniteRows(points_local, 3, "points_local", &n);
    for (size_t i = 0; i < n; ++i) {
      e.query.points_local.emplace_back(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
    }
  }
  if (!gravity.is_none())
    e.query.gravity_query = JsonVector3(ToJson(gravity, "gravity"), "gravity");
  if (!map_gravity.is_none()) {
    e.query.gravity_map = JsonVector3(ToJson(map_gravity, "map_gravity"), "map_gravity");
  }
  if (!ransac.is_none()) SetRansac(ToJson(ransac, "ransac"), &e.options.ransac);
  SetRefine(refine, &e.options);
  SetSuccess(success, &e.options);
  e.options.Check();
  return e;
}

py::tuple ResultToPython(const Estimate& e, const LocalizeResult& r) {
  py::object pose = py::none();
  if (r.has_pose) {
    pose = PoseObject(r.query_from_world.rotation, r.query_from_world.translation,
                      e.method->similarity() ? r.query_from_world.scale : 1.0);
  }
  py::array_t<bool> mask(static_cast<py::ssize_t>(e.query.observations.size()));
  std::fill_n(mask.mutable_data(), mask.size(), false);
  for (const int i : r.inliers) mask.mutable_data()[i] = true;
  py::dict info;
  info["success"] = r.success;
  if (!r.success) info["reason"] = r.failure;
  info["num_inliers"] = r.inliers.size();
  info["inliers"] = mask;  // PoseLib's convention: a mask over the correspondences
  // The Localizer's convention (its results' "inliers"): the indices, ascending.
  py::array_t<int64_t> indices(static_cast<py::ssize_t>(r.inliers.size()));
  std::vector<int> sorted = r.inliers;
  std::sort(sorted.begin(), sorted.end());
  std::copy(sorted.begin(), sorted.end(), indices.mutable_data());
  info["inlier_indices"] = indices;
  info["inlier_ratio"] =
      r.num_correspondences ? double(r.inliers.size()) / r.num_correspondences : 0.0;
  info["iterations"] = r.stats.iterations;
  info["refine_iterations"] = r.refine_iterations;
  info["rejected_observations"] = r.rejected_observations;
  info["reprojection_px"] = py::dict(py::arg("initial") = r.reprojection_initial_px,
                                     py::arg("refined") = r.reprojection_refined_px);
  info["rotation_uncertainty_deg"] = r.uncertainty.rotation_deg;
  info["ransac_ms"] = r.stats.ransac_ms;
  info["refine_ms"] = r.refine_ms;
  return py::make_tuple(pose, info);
}

#define LINECLOUD_ESTIMATE_ARGS                                                                 \
  py::arg("method"), py::arg("points2D"), py::arg("lines_or_points3D"), py::arg("camera"),      \
      py::kw_only(), py::arg("ransac") = py::none(), py::arg("refine") = py::none(),            \
                     py::arg("success") = py::none(), py::arg("gravity") = py::none(),          \
                     py::arg("map_gravity") = py::none(), py::arg("points_local") = py::none(), \
                     py::arg("cam_from_rig") = py::none()

py::tuple EstimatePose(const std::string& method, ArrayArg points2D, ArrayArg map_side,
                       CameraArg camera, OptionsArg ransac, OptionsArg refine, OptionsArg success,
                       VectorArg gravity, VectorArg map_gravity, VectorArg points_local,
                       PosesArg cam_from_rig) {
  const Estimate e = MakeEstimate(method, points2D, map_side, camera, ransac, refine, success,
                                  gravity, map_gravity, points_local, cam_from_rig);
  // Ctrl-C: RANSAC polls Python's signal handlers while it runs without the GIL (a handler that
  // raises stops it and the exception is raised here); at exit the thread parks (bindings.h).
  LocalizeOptions options = e.options;
  options.ransac.should_stop = PythonSignalRaised;
  LocalizeResult r;
  {
    GilReleased release;
    r = Localize(*e.method, e.query, e.map, options, kEstimate);
  }
  if (PyErr_Occurred()) throw py::error_already_set();
  return ResultToPython(e, r);
}

// The C++ peer of estimate_pose for the overhead benchmark: the same
// instance prepared once, Localize timed `repeats` times without Python.
std::vector<double> TimeEstimatePose(int repeats, const std::string& method, py::handle points2D,
                                     py::handle map_side, py::handle camera, py::handle ransac,
                                     py::handle refine, py::handle success, py::handle gravity,
                                     py::handle map_gravity, py::handle points_local,
                                     py::handle cam_from_rig) {
  if (repeats < 1 || repeats > 1'000'000) Fail("repeats must be in [1, 1e6], got {}", repeats);
  const Estimate e = MakeEstimate(method, points2D, map_side, camera, ransac, refine, success,
                                  gravity, map_gravity, points_local, cam_from_rig);
  std::vector<double> seconds;
  GilReleased release;
  for (int k = 0; k < repeats; ++k) {
    const auto start = std::chrono::steady_clock::now();
    const LocalizeResult r = Localize(*e.method, e.query, e.map, e.options, kEstimate);
    seconds.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    if (r.num_correspondences < 0) Fail("unreachable");  // keeps the call observable
  }
  return seconds;
}

py::list Solve(const std::string& method, const py::kwargs& sample) {
  nlohmann::json j = Options(
      sample, {"bearings", "camera_index", "cam_from_rig", "points_local", "points", "lines"},
      "solve");
  j["method"] = method;
  const MinimalProblem problem = ParseProblemJson(j, "solve");
  std::vector<Sim3d> solutions;
  {
    GilReleased release;
    SolveMinimal(*problem.method, problem.sample, &solutions);
  }
  py::list out;
  for (const Sim3d& s : solutions) {
    out.append(PoseObject(s.rotation, s.translation, problem.method->similarity() ? s.scale : 1.0));
  }
  return out;
}

py::list Methods() {
  py::list out;
  for (const MethodInfo& m : AllMethods()) {
    py::dict d;
    d["name"] = std::string(m.name);
    d["sample_size"] = m.sample_size;
    d["lines"] = m.lines;
    d["multi"] = m.multi;
    d["local_points"] = m.local_points;
    d["known_scale"] = m.known_scale;
    d["gravity"] = m.gravity;
    d["similarity"] = m.similarity();
    d["implemented"] = m.implemented;
    out.append(d);
  }
  return out;
}

}  // namespace

void BindEstimation(py::module_& m) {
  m.def("estimate_pose", &EstimatePose, LINECLOUD_ESTIMATE_ARGS,
        "Robust pose from 2D-3D correspondences (PoseLib's convention): RANSAC with the "
        "method's minimal solver, then LM. points2D N x 2 pixels (COLMAP's convention), "
        "lines_or_points3D N x 6 Pluecker lines (L methods) or N x 3 points (P methods), camera "
        "a camera dict; m- methods take lists, one per camera, and cam_from_rig. ransac: "
        "max_error (px), confidence, min_iterations, max_iterations, seed, max_seconds, "
        "local_optimization; refine: False or max_iterations, loss_scale, ...; success: False "
        "(every RANSAC pose counts) or min_inliers, min_inlier_ratio, ... Returns (pose, info): "
        "pose {q, t[, scale]} cam_from_world (None when RANSAC found none), info with success, "
        "reason, num_inliers, inliers (a bool mask, as PoseLib's), inlier_indices (the "
        "Localizer's convention), iterations, ...");
  m.def("_time_estimate_pose", &TimeEstimatePose, py::arg("repeats"), LINECLOUD_ESTIMATE_ARGS,
        "Seconds of each of `repeats` C++ calls on the prepared instance (the benchmark's peer).");
  m.def("solve", &Solve, py::arg("method"),
        "Every solution of one minimal solver on one minimal sample; fields as solve's "
        "PROBLEM.json: bearings, camera_index, cam_from_rig, points_local, points, lines. Returns "
        "a list of poses {q, t[, scale]}.");
  m.def("methods", &Methods,
        "The 16 methods of Speciale et al. (CVPR 2019), in the paper's order.");
}

}  // namespace linecloud::python
