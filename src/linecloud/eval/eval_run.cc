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

constexpr double kDeg = 180.0 / std::numbers::pi;

// Recall thresholds (rotation °, translation in the work's units).
constexpr std::pair<double, double> kRecall[] = {
    {0.25, 0.025}, {0.5, 0.05}, {1, 0.1}, {2, 0.25}, {5, 1}};

struct GroupMaps {
  PointMap points;
  LineMap lines;
};

// One query's row of the report (eval_report.h).
using QueryRecord = EvalQueryResult;

struct EvalQuery {
  std::string group, name;
  Query query;
  Sim3d truth;
};

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
  const double noise_px = Median(errors) / std::sqrt(2 * std::numbers::ln2);
  r->noise_px = noise_px;
  const PreparedQuery prepared = PrepareQuery(method, q.query, map, q.name);
  // query_from_world = query_from_aligned ∘ aligned_pose ∘ aligned_from_map.
  const Sim3d aligned_truth =
      Sim3d(1.0, prepared.aligned_from_query, Eigen::Vector3d::Zero()) * q.truth *
      Sim3d(1.0, prepared.aligned_from_map.inverse(), Eigen::Vector3d::Zero());
  r->rotation_bound_deg = kDeg * RotationErrorBound(prepared.data, inliers, aligned_truth, noise_px,
                                                    method.similarity());
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
    r.query = q.name;
    r.correspondences = static_cast<int>(q.query.observations.size());
    const GroupMaps& m = maps[group_index.at(q.group)];
    const LocalizationMap map = method.lines ? LocalizationMap(m.lines) : LocalizationMap(m.points);
    try {
      const LocalizeResult res = Localize(method, q.query, map, lo, q.name);
      r.success = res.success;
      r.iterations = res.stats.iterations;
      r.inlier_ratio = res.stats.inlier_ratio;
      r.mean_solutions = res.stats.mean_solutions;
      r.solver_us = res.stats.solver_us;
      r.ransac_ms = res.stats.ransac_ms;
      r.refine_ms = res.refine_ms;
      if (res.success) {
        // Positions in the work's units also for Sim3 queries (the rig centre in the world frame
        // is scale-free).
        const LocalizationError initial = CompareLocalization(res.initial, q.truth);
        const LocalizationError refined = CompareLocalization(res.query_from_world, q.truth);
        r.rotation_deg = {initial.rotation_rad * kDeg, refined.rotation_rad * kDeg};
        r.translation = {initial.position, refined.position};
        r.reprojection_px = {
            res.reprojection_initial_px, res.reprojection_refined_px,
            PointReprojection(q.query, m.points, res.initial, res.inliers),
            PointReprojection(q.query, m.points, res.query_from_world, res.inliers)};
        // Without inlier points in front of the camera: no noise estimate, no bound.
        r.noise_px = 0;
        r.rotation_bound_deg = std::numeric_limits<double>::infinity();
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

EvalMethodReport MethodReport(std::vector<QueryRecord> records) {
  const double n = std::max<size_t>(1, records.size());
  EvalMethodReport m;
  m.queries = static_cast<int>(records.size());
  std::vector<double> rot[2], pos[2], bounds, noises;
  double normalized_sq = 0;  // Σ (refined rotation error / its bound)²
  int bounded = 0, successes = 0;
  ReprojectionErrors& reproj = m.reprojection_px;
  for (const QueryRecord& r : records) {
    rot[0].push_back(r.rotation_deg.initial);
    rot[1].push_back(r.rotation_deg.refined);
    pos[0].push_back(r.translation.initial);
    pos[1].push_back(r.translation.refined);
    m.mean_iterations += r.iterations / n;
    m.inlier_ratio += r.inlier_ratio / n;
    m.mean_solutions += r.mean_solutions / n;
    m.solver_us += r.solver_us / n;
    m.ransac_ms += r.ransac_ms / n;
    m.refine_ms += r.refine_ms / n;
    if (r.success) {
      ++successes;
      reproj.initial += r.reprojection_px.initial;
      reproj.refined += r.reprojection_px.refined;
      reproj.point_initial += r.reprojection_px.point_initial;
      reproj.point_refined += r.reprojection_px.point_refined;
      const double bound = r.rotation_bound_deg.value_or(INFINITY);
      bounds.push_back(bound);
      noises.push_back(r.noise_px.value_or(0));
      if (std::isfinite(bound) && bound > 0) {
        normalized_sq += std::pow(r.rotation_deg.refined / bound, 2);
        ++bounded;
      }
    }
    m.localized += r.rotation_deg.refined < 1.0 && r.translation.refined < 0.1;
  }
  for (const auto& [deg, t] : kRecall) {
    int hits = 0;
    for (const QueryRecord& r : records)
      hits += r.rotation_deg.refined < deg && r.translation.refined < t;
    m.recall[fmt::format("{:g}deg_{:g}", deg, t)] = records.empty() ? 0.0 : hits / n;
  }
  const double ns = std::max(1, successes);
  reproj = {reproj.initial / ns, reproj.refined / ns, reproj.point_initial / ns,
            reproj.point_refined / ns};
  m.median_rotation_deg = Median(rot[1]);
  m.median_translation = Median(pos[1]);
  m.median_rotation_deg_initial = Median(rot[0]);
  m.median_translation_initial = Median(pos[0]);
  // Cramér–Rao check of the refined rotation (see BoundRotation).
  m.median_noise_px = Median(noises);
  m.median_rotation_bound_deg = Median(bounds);
  if (bounded) m.rms_rotation_error_over_bound = std::sqrt(normalized_sq / bounded);
  m.per_query = std::move(records);
  return m;
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

// The paper's protocol: every method on the prepared correspondences.
void RunPaperProtocol(const EvalInputs& in, const EvalRunOptions& options, EvalReport* report) {
  const std::vector<GroupMaps> maps = LoadMaps(in.work, options.work_dir, in.key, options.lifting);
  for (const MethodInfo* m : in.methods) {
    const auto t0 = std::chrono::steady_clock::now();
    const EvalMethodReport& mr = report->methods[std::string(m->name)] =
        MethodReport(RunMethod(in.work, *m, maps, options));
    LogProgress(
        "[eval] {:<12} {:>3} queries, {:>3} localized, median {:.3f}° / {:.4f}, {:>6.1f} "
        "iterations, inliers {:.0f} %, reprojection {:.2f} px ({:.1f} s)",
        m->name, mr.queries, mr.localized, mr.median_rotation_deg, mr.median_translation,
        mr.mean_iterations, 100 * mr.inlier_ratio, mr.reprojection_px.refined, SecondsSince(t0));
  }
}

// The deployable protocol (needs the images and COLMAP's database).
void RunDirectMatchingStage(const EvalInputs& in, const EvalRunOptions& options,
                            EvalReport* report) {
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
  report->direct_matching = RunDirectMatching(in.work, options.work_dir, in.key, dm);
}

// Fig. 7: error vs. map density (the run's own density from the paper's protocol above).
void RunDensitySweep(const EvalInputs& in, const EvalRunOptions& options, EvalReport* report) {
  if (options.density_sweep.empty()) return;
  EvalSweep d;
  d.levels = options.density_sweep;
  for (double drop : options.density_sweep) {
    const auto t0 = std::chrono::steady_clock::now();
    MapLifting at_drop = options.lifting;
    at_drop.sparsify = drop;
    const std::vector<GroupMaps> maps = LoadMaps(in.work, options.work_dir, in.key, at_drop);
    for (const MethodInfo* m : in.methods) {
      const std::string name(m->name);
      const EvalMethodReport mr = drop == options.lifting.sparsify
                                      ? report->methods.at(name)
                                      : MethodReport(RunMethod(in.work, *m, maps, options));
      d.median_rotation_deg[name].push_back(mr.median_rotation_deg);
      d.median_translation[name].push_back(mr.median_translation);
    }
    LogProgress("[eval] map density: {:.0f} % of the points dropped ({:.1f} s)", 100 * drop,
                SecondsSince(t0));
  }
  report->density = std::move(d);
}

// Fig. 8: error vs. pixel noise on the synthetic scene.
void RunNoiseSweep(const EvalInputs& in, const EvalRunOptions& options, EvalReport* report) {
  if (options.noise_sweep.empty()) return;
  EvalSweep d;
  d.levels = options.noise_sweep;
  d.queries_per_level = options.noise_sweep_queries;
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
      d.median_rotation_deg[std::string(m->name)].push_back(s.median_rotation_deg[1]);
      d.median_translation[std::string(m->name)].push_back(s.median_position[1] / scene.extent);
    }
    LogProgress("[eval] synthetic noise {} px ({:.1f} s)", noise, SecondsSince(t0));
  }
  report->noise = std::move(d);
}

// report.json, report.md and the figures, each from the report alone.
void WriteReports(const EvalReport& report, const std::string& out_dir) {
  WriteFileAtomically(JoinPaths(out_dir, "report.json"),
                      [&](std::ostream& o) { o << ToJson(report).dump(1) << "\n"; });
  const std::string md = EvalReportMarkdown(report);
  WriteFileAtomically(JoinPaths(out_dir, "report.md"), [&](std::ostream& o) { o << md; });
  WriteEvalFigures(report, out_dir);
  LogProgress("[eval] wrote {}/report.json, report.md and PNG plots", out_dir);
}

}  // namespace

// One stage per function: inputs, the paper's protocol, direct matching, Fig. 7, Fig. 8, the
// reports (Fig. 5 among the figures).
EvalReport RunEvaluation(const EvalRunOptions& options) {
  options.Check();
  const EvalInputs in = LoadInputs(options);
  CreateDirectories(options.out_dir);
  EvalReport report;
  report.dataset = in.work.dataset;
  report.units = in.work.units;
  report.threshold_px = options.threshold_px;
  report.sparsify = options.lifting.sparsify;
  report.lifting = options.lifting.Name();
  report.noise_px = options.noise_px;
  report.seed = options.seed;
  report.gravity_source = in.work.gravity_source;
  report.reconstruction = in.work.reconstruction;
  RunPaperProtocol(in, options, &report);
  RunDirectMatchingStage(in, options, &report);
  RunDensitySweep(in, options, &report);
  RunNoiseSweep(in, options, &report);
  WriteReports(report, options.out_dir);
  return report;
}

}  // namespace linecloud
