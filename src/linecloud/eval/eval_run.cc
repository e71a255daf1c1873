#include "linecloud/util/log.h"
#include "linecloud/eval/eval_run.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <set>

#include <fmt/core.h>

#include "linecloud/eval/direct_matching.h"
#include "linecloud/estimation/refine_pose.h"
#include "linecloud/benchmarks/localization_bench.h"
#include "linecloud/eval/paper_table2.h"
#include "linecloud/draw/plot.h"
#include "linecloud/benchmarks/scene_localization.h"
#include "linecloud/util/statistics.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/io/json_util.h"
#include "linecloud/lifting/key.h"
#include "linecloud/lifting/lifting.h"
#include "linecloud/lifting/sparsify.h"
#include "linecloud/privacy/map_lifting.h"
#include "linecloud/localize/localize.h"
#include "linecloud/synthetic/localization_instances.h"
#include "linecloud/synthetic/scene.h"
#include "linecloud/util/clock.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

using nlohmann::json;
constexpr double kDeg = 180.0 / std::numbers::pi;

// Recall thresholds (rotation °, translation in the work's units).
constexpr std::pair<double, double> kRecall[] = {
    {0.25, 0.025}, {0.5, 0.05}, {1, 0.1}, {2, 0.25}, {5, 1}};

struct GroupMaps {
  PointMap points;
  LineMap lines;
};

struct QueryRecord {
  std::string group, name;
  int correspondences = 0;
  bool success = false;
  std::string error;
  double rotation_deg[2] = {180, 180};
  double position[2] = {1e9, 1e9};
  double reprojection_px[2] = {0, 0};
  double point_reprojection_px[2] = {0, 0};
  // Observation noise σ̂ estimated at the ground truth (px), and the
  // Cramér–Rao bound of the refined rotation on the method's inliers with it
  // (°; +∞ when the inliers do not fix the pose).
  double noise_px = 0;
  double rotation_bound_deg = std::numeric_limits<double>::infinity();
  RansacStats stats;
  double refine_ms = 0;
};

struct EvalQuery {
  std::string group, name;
  Query query;
  Sim3d truth;
};

// JSON has no infinity: an unbounded value is written as null.
json FiniteOrNull(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

// One method's queries: single images, or each group as a rig; +l methods
// use the correspondences that have a local point; without known scale the
// local points and the rig are in the local reconstruction's own scale.
std::vector<EvalQuery> QueriesForMethod(const EvalWork& work, const MethodInfo& method,
                                        const std::vector<GroupMaps>& maps) {
  std::vector<EvalQuery> out;
  for (size_t gi = 0; gi < work.groups.size(); ++gi) {
    const EvalGroup& g = work.groups[gi];
    const auto& ids = maps[gi].points.points;
    if (!method.multi) {
      for (const EvalImage& im : g.images) {
        EvalQuery q{g.name, im.name, {}, ToSim3(im.cam_from_world)};
        q.query.cameras = {work.cameras.at(im.camera_id)};
        for (const EvalCorrespondence& c : im.correspondences) {
          if (ids.count(c.point_id))
            q.query.observations.push_back({0, c.xy, c.point_id, std::nullopt, std::nullopt});
        }
        if (method.gravity) {
          q.query.gravity_query = im.gravity;
          q.query.gravity_map = work.gravity_world;
        }
        out.push_back(std::move(q));
      }
      continue;
    }
    if (!g.has_rig || g.images.size() < 2) continue;
    const PosedRig rig = PoseRig(g, method.similarity());
    std::string name = g.name;
    EvalQuery q{g.name, "", {}, rig.rig_from_world};
    q.query.cam_from_rig = rig.cam_from_rig;
    for (size_t c = 0; c < g.images.size(); ++c) {
      const EvalImage& im = g.images[c];
      name += (c ? "+" : ":") + im.name;
      q.query.cameras.push_back(work.cameras.at(im.camera_id));
      for (const EvalCorrespondence& corr : im.correspondences) {
        if (!ids.count(corr.point_id)) continue;
        if (method.local_points) {
          if (!corr.point_local) continue;
          q.query.points_local.push_back(rig.scale * *corr.point_local);
        }
        q.query.observations.push_back(
            {static_cast<int>(c), corr.xy, corr.point_id, std::nullopt, std::nullopt});
      }
    }
    q.name = name;
    if (method.gravity) {
      q.query.gravity_query = g.gravity_rig;
      q.query.gravity_map = work.gravity_world;
    }
    out.push_back(std::move(q));
  }
  return out;
}

// Reprojection errors (px) of the map's (secret) points over `inliers`;
// points behind a camera are left out.
std::vector<double> PointReprojections(const Query& query, const PointMap& map, const Sim3d& pose,
                                       const std::vector<int>& inliers) {
  std::vector<double> errors;
  for (int i : inliers) {
    const QueryObservation& o = query.observations[i];
    Eigen::Vector3d x = pose * map.points.at(o.id);
    if (!query.cam_from_rig.empty()) x = query.cam_from_rig[o.camera] * x;
    if (!(x.z() > 0)) continue;
    errors.push_back((query.cameras[o.camera].ImgFromCam(x) - o.xy).norm());
  }
  return errors;
}

double PointReprojection(const Query& query, const PointMap& map, const Sim3d& pose,
                         const std::vector<int>& inliers) {
  const std::vector<double> errors = PointReprojections(query, map, pose, inliers);
  double sum = 0;
  for (double e : errors) sum += e;
  return errors.empty() ? 0 : sum / errors.size();
}

// The noise the refinement faces and the best it can do with it: σ̂ from the
// median reprojection error of the inliers' secret points at the ground truth
// (the norm of a 2D Gaussian error is Rayleigh, median σ √(2 ln 2)), and the
// Cramér–Rao bound of the rotation on the method's own residuals (eq. 2 for
// points, eq. 6 for lines) at the ground truth, in the frames the refinement
// works in.
void BoundRotation(const MethodInfo& method, const EvalQuery& q, const LocalizationMap& map,
                   const PointMap& points, const std::vector<int>& inliers, QueryRecord* r) {
  const std::vector<double> errors = PointReprojections(q.query, points, q.truth, inliers);
  if (errors.empty()) return;
  r->noise_px = Median(errors) / std::sqrt(2 * std::numbers::ln2);
  const PreparedQuery prepared = PrepareQuery(method, q.query, map, q.name);
  // query_from_world = query_from_aligned ∘ aligned_pose ∘ aligned_from_map.
  const Sim3d aligned_truth =
      Sim3d(1.0, prepared.aligned_from_query, Eigen::Vector3d::Zero()) * q.truth *
      Sim3d(1.0, prepared.aligned_from_map.inverse(), Eigen::Vector3d::Zero());
  r->rotation_bound_deg = kDeg * RotationErrorBound(prepared.data, inliers, aligned_truth,
                                                    r->noise_px, method.similarity());
}

std::vector<QueryRecord> RunMethod(const EvalWork& work, const MethodInfo& method,
                                   const std::vector<GroupMaps>& maps,
                                   const EvalRunOptions& options) {
  std::vector<QueryRecord> records;
  std::map<std::string, size_t> group_index;
  for (size_t gi = 0; gi < work.groups.size(); ++gi) group_index[work.groups[gi].name] = gi;
  LocalizeOptions lo;
  lo.ransac.max_error = options.threshold_px;
  lo.ransac.seed = options.seed;
  // The paper's protocol judges every pose by its error to the ground truth.
  lo.success = SuccessCriteria::None();
  for (const EvalQuery& q : QueriesForMethod(work, method, maps)) {
    QueryRecord r;
    r.group = q.group;
    r.name = q.name;
    r.correspondences = static_cast<int>(q.query.observations.size());
    const GroupMaps& m = maps[group_index.at(q.group)];
    const LocalizationMap map = method.lines ? LocalizationMap(m.lines) : LocalizationMap(m.points);
    try {
      const LocalizeResult res = Localize(method, q.query, map, lo, q.name);
      r.success = res.success;
      r.stats = res.stats;
      r.refine_ms = res.refine_ms;
      if (res.success) {
        const Sim3d* est[2] = {&res.initial, &res.query_from_world};
        for (int k = 0; k < 2; ++k) {
          const LocalizationError e = CompareLocalization(*est[k], q.truth);
          r.rotation_deg[k] = e.rotation_rad * kDeg;
          // Positions in the work's units also for Sim3 queries (the rig
          // centre in the world frame is scale-free).
          r.position[k] = e.position;
          r.point_reprojection_px[k] = PointReprojection(q.query, m.points, *est[k], res.inliers);
        }
        r.reprojection_px[0] = res.reprojection_initial_px;
        r.reprojection_px[1] = res.reprojection_refined_px;
        BoundRotation(method, q, map, m.points, res.inliers, &r);
      } else {
        r.error = "RANSAC found no pose";
      }
    } catch (const Error& e) {
      r.error = e.what();
    }
    records.push_back(std::move(r));
  }
  return records;
}

json MethodReport(const std::vector<QueryRecord>& records) {
  const double n = std::max<size_t>(1, records.size());
  std::vector<double> rot[2], pos[2];
  double iterations = 0, inliers = 0, solutions = 0, solver_us = 0, ransac_ms = 0, refine_ms = 0;
  double reproj[2] = {0, 0}, point_reproj[2] = {0, 0};
  int localized = 0, successes = 0;
  std::vector<double> bounds, noises;
  double normalized_sq = 0;  // Σ (refined rotation error / its bound)²
  int bounded = 0;
  json per_query = json::array();
  for (const QueryRecord& r : records) {
    for (int k = 0; k < 2; ++k) {
      rot[k].push_back(r.rotation_deg[k]);
      pos[k].push_back(r.position[k]);
    }
    iterations += r.stats.iterations;
    inliers += r.stats.inlier_ratio;
    solutions += r.stats.mean_solutions;
    solver_us += r.stats.solver_us;
    ransac_ms += r.stats.ransac_ms;
    refine_ms += r.refine_ms;
    if (r.success) {
      ++successes;
      for (int k = 0; k < 2; ++k) {
        reproj[k] += r.reprojection_px[k];
        point_reproj[k] += r.point_reprojection_px[k];
      }
      bounds.push_back(r.rotation_bound_deg);
      noises.push_back(r.noise_px);
      if (std::isfinite(r.rotation_bound_deg) && r.rotation_bound_deg > 0) {
        normalized_sq += std::pow(r.rotation_deg[1] / r.rotation_bound_deg, 2);
        ++bounded;
      }
    }
    localized += r.rotation_deg[1] < 1.0 && r.position[1] < 0.1;
    json q = {{"group", r.group},
              {"query", r.name},
              {"correspondences", r.correspondences},
              {"success", r.success},
              {"rotation_deg", {{"initial", r.rotation_deg[0]}, {"refined", r.rotation_deg[1]}}},
              {"translation", {{"initial", r.position[0]}, {"refined", r.position[1]}}},
              {"iterations", r.stats.iterations},
              {"inlier_ratio", r.stats.inlier_ratio},
              {"mean_solutions", r.stats.mean_solutions},
              {"solver_us", r.stats.solver_us},
              {"ransac_ms", r.stats.ransac_ms},
              {"refine_ms", r.refine_ms},
              {"reprojection_px",
               {{"initial", r.reprojection_px[0]},
                {"refined", r.reprojection_px[1]},
                {"point_initial", r.point_reprojection_px[0]},
                {"point_refined", r.point_reprojection_px[1]}}}};
    if (r.success) {
      q["noise_px"] = r.noise_px;
      q["rotation_bound_deg"] = FiniteOrNull(r.rotation_bound_deg);
    }
    if (!r.error.empty()) q["error"] = r.error;
    per_query.push_back(q);
  }
  json recall = json::object();
  for (const auto& [deg, t] : kRecall) {
    int hits = 0;
    for (const QueryRecord& r : records) hits += r.rotation_deg[1] < deg && r.position[1] < t;
    recall[fmt::format("{:g}deg_{:g}", deg, t)] = records.empty() ? 0.0 : hits / n;
  }
  const double ns = std::max(1, successes);
  return {{"queries", records.size()},
          {"localized", localized},
          {"median_rotation_deg", Median(rot[1])},
          {"median_translation", Median(pos[1])},
          {"median_rotation_deg_initial", Median(rot[0])},
          {"median_translation_initial", Median(pos[0])},
          {"recall", recall},
          {"mean_iterations", iterations / n},
          {"inlier_ratio", inliers / n},
          {"mean_solutions", solutions / n},
          {"solver_us", solver_us / n},
          {"ransac_ms", ransac_ms / n},
          {"refine_ms", refine_ms / n},
          {"reprojection_px",
           {{"initial", reproj[0] / ns},
            {"refined", reproj[1] / ns},
            {"point_initial", point_reproj[0] / ns},
            {"point_refined", point_reproj[1] / ns}}},
          // Cramér–Rao check of the refined rotation (see BoundRotation).
          {"median_noise_px", Median(noises)},
          {"median_rotation_bound_deg", FiniteOrNull(Median(bounds))},
          {"rms_rotation_error_over_bound",
           bounded ? json(std::sqrt(normalized_sq / bounded)) : json(nullptr)},
          {"per_query", per_query}};
}

std::vector<GroupMaps> LoadMaps(const EvalWork& work, const std::string& work_dir,
                                const LiftingKey& key, const MapLifting& lifting) {
  std::vector<GroupMaps> maps;
  const LiftingKey lines_key = MapLiftingKey(key, lifting);
  for (const EvalGroup& g : work.groups) {
    const Reconstruction model = ReadColmapModel(JoinPaths(work_dir, g.map_dir));
    const std::vector<uint64_t> ids = model.SortedPoint3DIds();
    const std::vector<Eigen::Vector3d> xyz = PointCoordinates(model, ids);
    // The map `lift` would write with these options; the point model holds
    // the same (kept) points.
    GroupMaps m;
    m.lines = LineMapByPointId(LiftMap(key, ids, xyz, lifting), lines_key);
    for (const auto& [id, line] : m.lines.lines) m.points.points[id] = model.points3D.at(id).xyz;
    maps.push_back(std::move(m));
  }
  return maps;
}

// Pair colours: a point method and its line twin share a colour; lines dashed.
int PairColor(const MethodInfo& m) {
  const auto all = AllMethods();
  for (size_t i = 0; i < all.size(); ++i) {
    if (all[i].name == m.name) return static_cast<int>(i % 8);
  }
  return 0;
}

std::vector<double> CumulativeAt(std::vector<double> errors, const std::vector<double>& xs) {
  std::sort(errors.begin(), errors.end());
  std::vector<double> y;
  for (double x : xs) {
    const auto it = std::upper_bound(errors.begin(), errors.end(), x);
    y.push_back(errors.empty() ? 0.0 : 100.0 * (it - errors.begin()) / errors.size());
  }
  return y;
}

std::string Fixed(double v, int decimals) {
  return std::isfinite(v) ? fmt::format("{:.{}f}", v, decimals) : "–";
}

// A markdown table: one row per method (paper order), one column per sweep level.
std::string SweepTable(const std::vector<std::string>& columns, const json& values_by_method) {
  std::string md = "| method |";
  for (const std::string& c : columns) md += fmt::format(" {} |", c);
  md += "\n|---|";
  for (size_t i = 0; i < columns.size(); ++i) md += "---|";
  md += "\n";
  for (const MethodInfo& info : AllMethods()) {
    const std::string name(info.name);
    if (!values_by_method.contains(name)) continue;
    md += fmt::format("| {} |", name);
    for (double x : values_by_method[name]) md += fmt::format(" {} |", Fixed(x, 3));
    md += "\n";
  }
  return md;
}

std::string DirectMatchingMarkdown(const json& d) {
  std::string md = fmt::format(
      "\n## Direct matching (the deployable protocol)\n\nEach query image's own SIFT features "
      "(COLMAP 3.8's CPU extractor reproduced) matched to the map's descriptors (medoids of the "
      "map "
      "images' observations only), then the same RANSAC, refinement and success criteria as "
      "`localize --image`; the m- methods take each group's photos as one rig (`localize "
      "--image A --image B --rig RIG.json`). Localized: within {}° and {} units of the ground "
      "truth.\n\n"
      "| method | queries | localized | median rot. ° | median transl. | extract ms | match ms | "
      "RANSAC ms | refine ms |\n|---|---|---|---|---|---|---|---|---|\n",
      d["thresholds"]["rotation_deg"].get<double>(), d["thresholds"]["translation"].get<double>());
  for (const auto& [name, m] : d["methods"].items()) {
    const json& t = m["mean_ms"];
    md += fmt::format("| {} | {} | {} | {:.4f} | {:.4f} | {:.0f} | {:.0f} | {:.1f} | {:.1f} |\n",
                      name, m["queries"].get<int>(), m["localized"].get<int>(),
                      m["median_rotation_deg"].get<double>(), m["median_translation"].get<double>(),
                      t["extract"].get<double>(), t["match"].get<double>(),
                      t["ransac"].get<double>(), t["refine"].get<double>());
  }
  return md;
}

std::string ReportMarkdown(const EvalWork& work, const EvalRunOptions& options,
                           const json& report) {
  std::string md = fmt::format("# linecloud eval — {}\n\n", work.dataset);
  md += fmt::format(
      "Units: {}. RANSAC threshold {} px for every method; seed {}; map sparsified by {:.0f} %; "
      "extra pixel noise σ = {} px.\n\n",
      work.units, options.threshold_px, options.seed, 100 * options.lifting.sparsify,
      options.noise_px);
  if (work.reconstruction.contains("ground_truth")) {
    const json& g = work.reconstruction["ground_truth"];
    md += fmt::format(
        "COLMAP reconstruction vs. ground truth, after a similarity alignment on {} cameras "
        "(rotation from their orientations, scale and translation from their centres): "
        "max {:.3f}° / {:.4f} m.\n\n",
        g["aligned_on"].get<int>(), g["max_rotation_deg"].get<double>(),
        g["max_position_m"].get<double>());
  }
  md += fmt::format("Gravity (+u): {}.\n\n", work.gravity_source);
  md +=
      "Table 2 layout. Rotation error (°) and translation error; `loc.` = within 1° and 0.1; "
      "iterations, inlier ratio, solutions and solver time are means per query; reprojection "
      "errors (px) are means over the inliers: point-to-line for line methods with the "
      "point-to-point "
      "error against the secret points in brackets. Paper = Speciale et al., CVPR 2019, Table "
      "2.\n\n";
  md +=
      "| method | queries | loc. | rot. init / ref. | trans. init / ref. | iters | inliers % | "
      "solutions | solver µs | reproj. init / ref. px | paper: iters / inl. % / sol. | paper "
      "reproj. |\n";
  md += "|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const MethodInfo& info : AllMethods()) {
    const std::string name(info.name);
    if (!report["methods"].contains(name)) continue;
    const json& m = report["methods"][name];
    const bool lines = info.lines;
    const json& rp = m["reprojection_px"];
    std::string reproj = Fixed(rp["initial"], 2) + " / " + Fixed(rp["refined"], 2);
    if (lines) {
      reproj =
          fmt::format("{} ({}) / {} ({})", Fixed(rp["initial"], 2), Fixed(rp["point_initial"], 2),
                      Fixed(rp["refined"], 2), Fixed(rp["point_refined"], 2));
    }
    std::string paper = "–", paper_reproj = "–";
    if (const PaperRow* p = PaperFor(name)) {
      paper = fmt::format("{:g} / {:g} / {:g}", p->iterations, p->inlier_percent, p->solutions);
      if (p->reprojection_initial > 0)
        paper_reproj =
            fmt::format("{:.2f} / {:.2f}", p->reprojection_initial, p->reprojection_refined);
    }
    md += fmt::format(
        "| {} | {} | {} | {} / {} | {} / {} | {:.1f} | {:.0f} | {:.2f} | {:.1f} | {} | {} | {} |\n",
        name, m["queries"].get<int>(), m["localized"].get<int>(),
        Fixed(m["median_rotation_deg_initial"], 3), Fixed(m["median_rotation_deg"], 3),
        Fixed(m["median_translation_initial"], 4), Fixed(m["median_translation"], 4),
        m["mean_iterations"].get<double>(), 100 * m["inlier_ratio"].get<double>(),
        m["mean_solutions"].get<double>(), m["solver_us"].get<double>(), reproj, paper,
        paper_reproj);
  }
  md +=
      "\n## Cramér–Rao check of the refined rotation\n\n"
      "How close each method comes to the least rotation error any estimator could reach on its "
      "inliers: σ̂ = the observation noise at the ground truth (median reprojection error of the "
      "inliers' points / √(2 ln 2)), bound = √trace of the Cramér–Rao covariance of the rotation "
      "at the ground truth with σ̂ (eq. 2 residuals for points, eq. 6 for lines: a line measures "
      "only the offset across it), medians over the queries; RMS error / bound ≈ 1 for an "
      "efficient estimator. The bound ratio is the least by which the line method must trail its "
      "point twin on these queries.\n\n"
      "| point / line method | σ̂ px | refined rot. ° point / line (ratio) | bound ° point / line "
      "(ratio) | "
      "RMS error / bound point / line |\n|---|---|---|---|---|\n";
  for (const MethodInfo& info : AllMethods()) {
    const std::string name(info.name), twin = CounterpartMethod(info);
    if (info.lines || !report["methods"].contains(name) || !report["methods"].contains(twin))
      continue;
    const json& p = report["methods"][name];
    const json& l = report["methods"][twin];
    const auto value = [](const json& v) { return v.is_number() ? v.get<double>() : NAN; };
    const double rp = value(p["median_rotation_deg"]), rl = value(l["median_rotation_deg"]);
    const double bp = value(p["median_rotation_bound_deg"]),
                 bl = value(l["median_rotation_bound_deg"]);
    md += fmt::format("| {} / {} | {} | {} / {} ({}×) | {} / {} ({}×) | {} / {} |\n", name, twin,
                      Fixed(value(p["median_noise_px"]), 2), Fixed(rp, 4), Fixed(rl, 4),
                      Fixed(rl / rp, 2), Fixed(bp, 4), Fixed(bl, 4), Fixed(bl / bp, 2),
                      Fixed(value(p["rms_rotation_error_over_bound"]), 2),
                      Fixed(value(l["rms_rotation_error_over_bound"]), 2));
  }
  if (report.contains("density")) {
    std::vector<std::string> columns;
    for (double f : report["density"]["dropped"])
      columns.push_back(fmt::format("{:.0f} %", 100 * f));
    md +=
        "\n## Error vs. map density (Fig. 7)\n\nMedian refined rotation error (°) when a share of "
        "the "
        "map's points (and the same lines) is dropped at random.\n\n" +
        SweepTable(columns, report["density"]["median_rotation_deg"]);
  }
  if (report.contains("direct_matching")) md += DirectMatchingMarkdown(report["direct_matching"]);
  if (report.contains("noise")) {
    std::vector<std::string> columns;
    for (double f : report["noise"]["noise_px"]) columns.push_back(fmt::format("{:g} px", f));
    md +=
        "\n## Error vs. pixel noise, synthetic (Fig. 8)\n\nMedian refined rotation error (°).\n\n" +
        SweepTable(columns, report["noise"]["median_rotation_deg"]);
  }
  return md;
}

}  // namespace

void EvalRunOptions::Check() const {
  if (work_dir.empty()) Fail("--work: empty");
  if (out_dir.empty()) Fail("--out: empty");
  for (const std::string& m : methods) FindMethod(m);
  lifting.Check();
  if (!(noise_px >= 0 && std::isfinite(noise_px)))
    Fail("--noise: {} is not a pixel std. dev. >= 0", noise_px);
  if (!(threshold_px > 0 && std::isfinite(threshold_px)))
    Fail("--threshold: {} must be > 0", threshold_px);
  for (double f : density_sweep) {
    if (!(f >= 0 && f < 1)) Fail("density sweep: {} not in [0, 1)", f);
  }
  for (double n : noise_sweep) {
    if (!(n >= 0 && std::isfinite(n))) Fail("noise sweep: {} is not >= 0", n);
  }
  if (noise_sweep_queries < 1) Fail("noise sweep queries: {} < 1", noise_sweep_queries);
}

EvalWork ReadPreparedWork(const std::string& work_dir) {
  const std::string work_path = JoinPaths(work_dir, "prepared.json");
  if (!FileExists(work_path))
    Fail("{}: not found (run `linecloud eval prepare --work {}` first)", work_path, work_dir);
  return EvalWorkFromJson(ReadJsonFile(work_path), work_path);
}

LiftingKey EvalLiftingKey(const std::string& work_dir) {
  // The evaluation's maps are lifted with one permanent key per work directory.
  const std::string key_path = JoinPaths(work_dir, "lifting.key");
  if (!FileExists(key_path)) WriteKeyFile(key_path, LiftingKey::Generate());
  return ReadKeyFile(key_path);
}

namespace {

// The evaluation's inputs: the prepared work (with --noise added to the query
// pixels), its key and the methods to run.
struct EvalInputs {
  EvalWork work;
  LiftingKey key;
  std::vector<const MethodInfo*> methods;
};

EvalInputs LoadInputs(const EvalRunOptions& options) {
  EvalInputs in{ReadPreparedWork(options.work_dir), EvalLiftingKey(options.work_dir), {}};
  if (options.noise_px > 0) {
    std::mt19937_64 rng(options.seed);
    std::normal_distribution<double> noise(0.0, options.noise_px);
    for (EvalGroup& g : in.work.groups) {
      for (EvalImage& im : g.images) {
        for (EvalCorrespondence& c : im.correspondences)
          c.xy += Eigen::Vector2d(noise(rng), noise(rng));
      }
    }
  }
  if (options.methods.empty()) {
    for (const MethodInfo& m : AllMethods()) in.methods.push_back(&m);
  } else {
    for (const std::string& n : options.methods) in.methods.push_back(&FindMethod(n));
  }
  return in;
}

using RecordsByMethod = std::map<std::string, std::vector<QueryRecord>>;

// The paper's protocol: every method on the prepared correspondences.
RecordsByMethod RunPaperProtocol(const EvalInputs& in, const EvalRunOptions& options,
                                 json* report) {
  RecordsByMethod all_records;
  const std::vector<GroupMaps> maps = LoadMaps(in.work, options.work_dir, in.key, options.lifting);
  for (const MethodInfo* m : in.methods) {
    const auto t0 = std::chrono::steady_clock::now();
    std::vector<QueryRecord> records = RunMethod(in.work, *m, maps, options);
    json mr = MethodReport(records);
    LogProgress(
        "[eval] {:<12} {:>3} queries, {:>3} localized, median {:.3f}° / {:.4f}, {:>6.1f} "
        "iterations, "
        "inliers {:.0f} %, reprojection {:.2f} px ({:.1f} s)",
        m->name, mr["queries"].get<int>(), mr["localized"].get<int>(),
        mr["median_rotation_deg"].get<double>(), mr["median_translation"].get<double>(),
        mr["mean_iterations"].get<double>(), 100 * mr["inlier_ratio"].get<double>(),
        mr["reprojection_px"]["refined"].get<double>(), SecondsSince(t0));
    (*report)["methods"][std::string(m->name)] = mr;
    all_records[std::string(m->name)] = std::move(records);
  }
  return all_records;
}

// The deployable protocol (needs the images and COLMAP's database).
void RunDirectMatchingStage(const EvalInputs& in, const EvalRunOptions& options, json* report) {
  if (!options.direct_matching) return;
  if (!FileExists(JoinPaths(options.work_dir, "colmap/database.db"))) {
    LogProgress("[eval] direct matching skipped: {} has no COLMAP database", options.work_dir);
    return;
  }
  DirectMatchingOptions dm;
  dm.threshold_px = options.threshold_px;
  dm.seed = options.seed;
  dm.lifting = options.lifting;
  dm.extracted = options.extracted_photos;
  dm.image.sift.extractor = options.features;
  (*report)["direct_matching"] = RunDirectMatching(in.work, options.work_dir, in.key, dm);
}

// Fig. 5: cumulative error curves.
void WriteCumulativeFigures(const EvalInputs& in, const EvalRunOptions& options,
                            RecordsByMethod& all_records) {
  std::vector<double> xr, xt;
  // Log-spaced: 1e-3° .. 10°, 1e-4 .. 10 units.
  for (int i = 0; i <= 200; ++i) xr.push_back(std::pow(10.0, -3 + 4.0 * i / 200));
  for (int i = 0; i <= 250; ++i) xt.push_back(std::pow(10.0, -4 + 5.0 * i / 250));
  std::vector<PlotSeries> rs, ts;
  for (const MethodInfo* m : in.methods) {
    std::vector<double> r, t;
    for (const QueryRecord& q : all_records[std::string(m->name)]) {
      r.push_back(q.rotation_deg[1]);
      t.push_back(q.position[1]);
    }
    rs.push_back(
        {std::string(m->name), xr, CumulativeAt(r, xr), PairColor(*m), m->lines, false, {}});
    ts.push_back(
        {std::string(m->name), xt, CumulativeAt(t, xt), PairColor(*m), m->lines, false, {}});
  }
  WriteLinePlot(JoinPaths(options.out_dir, "cumulative_rotation.png"),
                {.title = in.work.dataset + ": cumulative rotation error (refined)",
                 .x_label = "rotation error (deg)",
                 .y_label = "queries (%)",
                 .log_x = true,
                 .y_min = 0,
                 .y_max = 100},
                rs);
  WriteLinePlot(JoinPaths(options.out_dir, "cumulative_translation.png"),
                {.title = in.work.dataset + ": cumulative translation error (refined)",
                 .x_label = "translation error (" + in.work.units + ")",
                 .y_label = "queries (%)",
                 .log_x = true,
                 .y_min = 0,
                 .y_max = 100},
                ts);
}

// Fig. 7: error vs. map density.
void RunDensitySweep(const EvalInputs& in, const EvalRunOptions& options,
                     RecordsByMethod& all_records, json* report) {
  if (options.density_sweep.empty()) return;
  json d = {{"dropped", options.density_sweep},
            {"median_rotation_deg", json::object()},
            {"median_translation", json::object()}};
  std::map<std::string, std::vector<double>> rot, pos;
  for (double drop : options.density_sweep) {
    const auto t0 = std::chrono::steady_clock::now();
    MapLifting at_drop = options.lifting;
    at_drop.sparsify = drop;
    const std::vector<GroupMaps> maps = LoadMaps(in.work, options.work_dir, in.key, at_drop);
    for (const MethodInfo* m : in.methods) {
      std::vector<QueryRecord> records = drop == options.lifting.sparsify
                                             ? all_records[std::string(m->name)]
                                             : RunMethod(in.work, *m, maps, options);
      std::vector<double> r, t;
      for (const QueryRecord& q : records) {
        r.push_back(q.rotation_deg[1]);
        t.push_back(q.position[1]);
      }
      rot[std::string(m->name)].push_back(Median(r));
      pos[std::string(m->name)].push_back(Median(t));
    }
    LogProgress("[eval] map density: {:.0f} % of the points dropped ({:.1f} s)", 100 * drop,
                SecondsSince(t0));
  }
  std::vector<PlotSeries> series;
  for (const MethodInfo* m : in.methods) {
    const std::string n(m->name);
    d["median_rotation_deg"][n] = rot[n];
    d["median_translation"][n] = pos[n];
    std::vector<double> x;
    for (double f : options.density_sweep) x.push_back(100 * f);
    series.push_back({n, x, rot[n], PairColor(*m), m->lines, false, {}});
  }
  (*report)["density"] = d;
  WriteLinePlot(JoinPaths(options.out_dir, "error_vs_density.png"),
                {.title = in.work.dataset + ": median rotation error vs. map density",
                 .x_label = "points / lines dropped (%)",
                 .y_label = "median rotation error (deg)",
                 .log_y = true},
                series);
}

// Fig. 8: error vs. pixel noise on the synthetic scene.
void RunNoiseSweep(const EvalInputs& in, const EvalRunOptions& options, json* report) {
  if (options.noise_sweep.empty()) return;
  json d = {{"noise_px", options.noise_sweep},
            {"queries_per_level", options.noise_sweep_queries},
            {"median_rotation_deg", json::object()},
            {"median_translation_relative", json::object()}};
  std::map<std::string, std::vector<double>> rot, pos;
  for (double noise : options.noise_sweep) {
    const auto t0 = std::chrono::steady_clock::now();
    SyntheticSceneOptions so;
    so.noise_px = noise;
    so.num_queries = options.noise_sweep_queries;
    so.seed = options.seed;
    const SyntheticScene scene = GenerateSyntheticScene(so);
    const std::vector<uint64_t> ids = scene.model.SortedPoint3DIds();
    std::vector<Eigen::Vector3d> xyz;
    for (uint64_t id : ids) xyz.push_back(scene.model.points3D.at(id).xyz);
    const PointMap point_map = PointMapFromModel(scene.model);
    const LineMap line_map =
        LineMapByPointId(LiftPoints(ids, xyz, in.key, {LineEncoding::kPlucker}), in.key);
    SceneQueryOptions qo;
    qo.seed = options.seed;
    LocalizeOptions lo;
    lo.success = SuccessCriteria::None();
    lo.ransac.max_error = std::max(options.threshold_px, 3 * noise);
    lo.ransac.seed = options.seed;
    for (const MethodInfo* m : in.methods) {
      const auto queries = SceneQueriesForMethod(scene, *m, qo);
      const MethodSummary s = EvaluateMethod(
          *m, queries, m->lines ? LocalizationMap(line_map) : LocalizationMap(point_map), lo, 1.0,
          0.01 * scene.extent);
      rot[std::string(m->name)].push_back(s.median_rotation_deg[1]);
      pos[std::string(m->name)].push_back(s.median_position[1] / scene.extent);
    }
    LogProgress("[eval] synthetic noise {} px ({:.1f} s)", noise, SecondsSince(t0));
  }
  std::vector<PlotSeries> series;
  for (const MethodInfo* m : in.methods) {
    const std::string n(m->name);
    d["median_rotation_deg"][n] = rot[n];
    d["median_translation_relative"][n] = pos[n];
    series.push_back({n, options.noise_sweep, rot[n], PairColor(*m), m->lines, false, {}});
  }
  (*report)["noise"] = d;
  WriteLinePlot(JoinPaths(options.out_dir, "error_vs_noise.png"),
                {.title = "synthetic scene: median rotation error vs. pixel noise",
                 .x_label = "pixel noise σ (px)",
                 .y_label = "median rotation error (deg)",
                 .log_y = true},
                series);
}

void WriteReports(const EvalWork& work, const EvalRunOptions& options, const json& report) {
  WriteFileAtomically(JoinPaths(options.out_dir, "report.json"),
                      [&](std::ostream& o) { o << report.dump(1) << "\n"; });
  const std::string md = ReportMarkdown(work, options, report);
  WriteFileAtomically(JoinPaths(options.out_dir, "report.md"), [&](std::ostream& o) { o << md; });
  LogProgress("[eval] wrote {}/report.json, report.md and PNG plots", options.out_dir);
}

}  // namespace

// One stage per function: inputs, the paper's protocol, direct matching,
// Fig. 5, Fig. 7, Fig. 8, the reports.
json RunEvaluation(const EvalRunOptions& options) {
  options.Check();
  const EvalInputs in = LoadInputs(options);
  CreateDirectories(options.out_dir);
  json report = {{"dataset", in.work.dataset},
                 {"units", in.work.units},
                 {"threshold_px", options.threshold_px},
                 {"sparsify", options.lifting.sparsify},
                 {"lifting", options.lifting.Name()},
                 {"noise_px", options.noise_px},
                 {"seed", options.seed},
                 {"gravity_source", in.work.gravity_source},
                 {"reconstruction", in.work.reconstruction}};
  report["methods"] = json::object();
  RecordsByMethod all_records = RunPaperProtocol(in, options, &report);
  RunDirectMatchingStage(in, options, &report);
  WriteCumulativeFigures(in, options, all_records);
  RunDensitySweep(in, options, all_records, &report);
  RunNoiseSweep(in, options, &report);
  WriteReports(in.work, options, report);
  return report;
}

}  // namespace linecloud
