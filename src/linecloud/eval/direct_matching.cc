#include "linecloud/util/log.h"
#include "linecloud/eval/direct_matching.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "linecloud/util/statistics.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/lifting/lifting.h"
#include "linecloud/pipeline/localizer.h"
#include "linecloud/privacy/map_lifting.h"
#include "linecloud/synthetic/localization_instances.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

// A group's map as `localize --image` answers it: one Localizer on its lines,
// which matches the photos to the map's descriptors (ids are point ids: the
// lines are the owner's view, keyed by point id), and one on its points,
// which localizes those same correspondences.
struct GroupMap {
  std::optional<Localizer> lines, points;
  const Localizer& For(const MethodInfo& method) const { return method.lines ? *lines : *points; }
};

GroupMap LoadGroupMap(const std::string& work_dir, const EvalGroup& g, const LiftingKey& key,
                      const DirectMatchingOptions& options) {
  GroupMapData data = LoadGroupMapData(work_dir, g, key, options.lifting);
  LocalizerOptions o;
  o.image = options.image;
  o.localize.ransac.max_error = options.threshold_px;
  o.localize.ransac.seed = options.seed;
  GroupMap m;
  m.lines.emplace(std::move(data.lines), std::move(data.descriptors), o, g.name);
  // Photos are matched once, on the lines' Localizer: the points' only takes
  // those queries (no second copy of the descriptors, no second index).
  m.points.emplace(std::move(data.points), std::nullopt, o, g.name);
  return m;
}

}  // namespace

GroupMapData LoadGroupMapData(const std::string& work_dir, const EvalGroup& g,
                              const LiftingKey& key, const MapLifting& lifting) {
  const Reconstruction model = ReadColmapModel(JoinPaths(work_dir, g.map_dir));
  std::vector<std::string> names;
  for (const EvalImage& im : g.images) names.push_back(im.name);
  const MapDescriptors all =
      MapDescriptorsExcluding(model, JoinPaths(work_dir, "colmap/database.db"), names);
  const std::vector<uint64_t> model_ids = model.SortedPoint3DIds();
  const std::vector<Eigen::Vector3d> model_xyz = PointCoordinates(model, model_ids);
  const LiftingKey lines_key = MapLiftingKey(key, lifting);
  const LineMap all_lines =
      LineMapByPointId(LiftMap(key, model_ids, model_xyz, lifting), lines_key);
  GroupMapData out;
  for (size_t k = 0; k < all.ids.size(); ++k) {
    const auto line = all_lines.lines.find(all.ids[k]);
    if (line == all_lines.lines.end()) continue;
    out.descriptors.ids.push_back(all.ids[k]);
    out.descriptors.descriptors.insert(out.descriptors.descriptors.end(),
                                       all.descriptors.begin() + k * 128,
                                       all.descriptors.begin() + (k + 1) * 128);
    out.lines.lines.emplace(line->first, line->second);
    out.points.points[all.ids[k]] = model.points3D.at(all.ids[k]).xyz;
  }
  return out;
}

MapDescriptors MapDescriptorsExcluding(const Reconstruction& map, const std::string& database,
                                       const std::vector<std::string>& excluded_images) {
  for (const auto& [id, image] : map.images) {
    for (const std::string& name : excluded_images) {
      if (image.name == name) {
        Fail(
            "the map registers the query image {}: its descriptors would reach the map it is "
            "localized against",
            name);
      }
    }
  }
  return MapDescriptorsFromModel(map, database);
}

namespace {

// The photo's features: extracted now, or once into `cache` and copied from
// it (without its pixels).
ImageQuery ExtractOnce(const std::string& path, const Camera& camera,
                       const ImageQueryOptions& options, ExtractedPhotos* cache) {
  if (!cache) return ExtractImageQuery(path, camera, options);
  const std::string key = std::string(SiftExtractorName(options.sift.extractor)) + ":" + path;
  auto it = cache->find(key);
  if (it == cache->end()) {
    ImageQuery q = ExtractImageQuery(path, camera, options);
    q.image = GreyImage{};
    it = cache->emplace(key, std::move(q)).first;
  }
  return it->second;
}

// The photo's features matched through the group's Localizer, as `localize
// --image` matches them (the same index rules); its extraction time kept.
ImageQuery MatchPhoto(const GroupMap& map, const ImageQuery& extracted, const Camera& camera,
                      const std::string& name) {
  QueryPhoto photo;
  photo.features = &extracted.features;
  photo.camera = camera;
  photo.name = name;
  ImageQuery q = map.lines->MatchPhoto(photo);
  q.times.decode_ms = extracted.times.decode_ms;
  q.times.extract_ms = extracted.times.extract_ms;
  return q;
}

constexpr double kDeg = 180.0 / std::numbers::pi;

struct Tally {
  std::vector<double> rotation, translation;
  int localized = 0;
  double extract_ms = 0, match_ms = 0, ransac_ms = 0, refine_ms = 0;
  double solver_ms = 0, scoring_ms = 0, lo_ms = 0, iterations = 0;
};

// One method on one query (a photo or a rig's photos): Localize as
// `localize --image` does, the error against `truth` into the tally and the
// row. `extract_ms` / `match_ms`: the query's photos' stage times.
void LocalizeQuery(const MethodInfo& method, const Query& query, const GroupMap& map,
                   const Sim3d& truth, double extract_ms, double match_ms, std::string_view source,
                   const DirectMatchingOptions& options, Tally* t, DirectMatchingAttempt* row) {
  double rot = 180, trans = 1e9;
  std::string failure;
  if (query.observations.size() >= static_cast<size_t>(method.sample_size)) {
    LocalizeRequest request;
    request.method = method.name;
    const LocalizeResult r = map.For(method).LocalizeQuery(query, request, source).pose;
    t->ransac_ms += r.stats.ransac_ms;
    t->solver_ms += r.stats.solver_ms;
    t->scoring_ms += r.stats.scoring_ms;
    t->lo_ms += r.stats.lo_ms;
    t->iterations += r.stats.iterations;
    row->attempted = true;
    row->ransac_ms = r.stats.ransac_ms;
    row->iterations = r.stats.iterations;
    row->uniform_iterations = r.stats.uniform_iterations;
    row->inliers = static_cast<int>(r.inliers.size());
    row->success = r.success;
    row->camera_inliers.assign(r.camera_inliers.begin(), r.camera_inliers.end());
    row->stop_reason = r.stats.stop_reason;
    if (r.has_pose) {
      row->sigma_px = r.uncertainty.sigma_px;
      if (std::isfinite(r.uncertainty.rotation_deg)) {
        row->sigma_rotation_deg = r.uncertainty.rotation_deg;
      }
      if (std::isfinite(r.uncertainty.position)) row->sigma_position = r.uncertainty.position;
    }
    t->refine_ms += r.refine_ms;
    failure = r.failure;
    if (r.success) {
      const LocalizationError e = CompareLocalization(r.query_from_world, truth);
      rot = e.rotation_rad * kDeg;
      trans = e.position;
    }
  } else {
    failure = "too few matches";
  }
  t->extract_ms += extract_ms;
  t->match_ms += match_ms;
  t->rotation.push_back(rot);
  t->translation.push_back(trans);
  t->localized += rot <= options.max_rotation_deg && trans <= options.max_translation;
  row->rotation_deg = rot;
  row->translation = trans;
  row->failure = failure;
}

// The group's photos as one generalized camera, with the rig the work holds
// (from calibration or the group's local reconstruction; in that one's own
// scale for the +s methods, as `eval run` poses them).
void LocalizeRig(const EvalWork& work, const EvalGroup& g, const GroupMap& map,
                 const std::vector<ImageQuery>& photos, const DirectMatchingOptions& options,
                 std::map<std::string, Tally>* tallies, std::vector<DirectMatchingRig>* per_rig) {
  DirectMatchingRig row;
  row.group = g.name;
  double extract_ms = 0, match_ms = 0;
  size_t matches = 0;
  for (size_t c = 0; c < photos.size(); ++c) {
    row.images.push_back(g.images[c].name);
    extract_ms += photos[c].times.extract_ms;
    match_ms += photos[c].times.match_ms;
    matches += photos[c].matches.size();
  }
  row.matches = static_cast<int>(matches);
  // The rig's own disagreement with the truth (worst camera): a floor under
  // any rig pose's error.
  double rig_rot = 0, rig_trans = 0;
  for (const EvalImage& im : g.images) {
    const LocalizationError e =
        CompareLocalization(ToSim3(im.cam_from_rig * g.rig_from_world), ToSim3(im.cam_from_world));
    rig_rot = std::max(rig_rot, e.rotation_rad * kDeg);
    rig_trans = std::max(rig_trans, e.position);
  }
  row.rig_error_rotation_deg = rig_rot;
  row.rig_error_translation = rig_trans;
  for (const std::string& name : options.rig_methods) {
    const MethodInfo& method = FindMethod(name);
    const PosedRig rig = PoseRig(g, method.similarity());
    Query query = CombineImageQueries(photos, rig.cam_from_rig);
    if (method.gravity) {
      query.gravity_query = g.gravity_rig;
      query.gravity_map = work.gravity_world;
    }
    LocalizeQuery(method, query, map, rig.rig_from_world, extract_ms, match_ms, g.name, options,
                  &(*tallies)[name], &row.methods[name]);
  }
  per_rig->push_back(std::move(row));
}

}  // namespace

namespace {

// One photo of `work` matched to `map` and localized by every method of the options: its row
// (under `group`), its matched query returned.
ImageQuery LocalizePhoto(const EvalWork& work, const EvalImage& im, const GroupMap& map,
                         const std::string& group, const DirectMatchingOptions& options,
                         std::map<std::string, Tally>* tallies, DirectMatchingPhoto* row) {
  const std::string path = JoinPaths(JoinPaths(work.dataset_dir, "images"), im.name);
  const Camera& camera = work.cameras.at(im.camera_id);
  ImageQuery q = MatchPhoto(map, ExtractOnce(path, camera, options.image, options.extracted.get()),
                            camera, path);
  *row = {group,
          im.name,
          static_cast<int>(q.features.size()),
          static_cast<int>(q.matches.size()),
          q.times.extract_ms,
          q.times.match_ms,
          {}};
  for (const std::string& name : options.methods) {
    LocalizeQuery(FindMethod(name), q.query, map, ToSim3(im.cam_from_world), q.times.extract_ms,
                  q.times.match_ms, im.name, options, &(*tallies)[name], &row->methods[name]);
  }
  return q;
}

}  // namespace

DirectMatchingReport RunOtherPlace(const EvalWork& photos, const EvalWork& map_work,
                                   const std::string& map_work_dir, const LiftingKey& key,
                                   const DirectMatchingOptions& options) {
  if (map_work.groups.empty()) Fail("other place: {} has no group", map_work_dir);
  const EvalGroup& g = map_work.groups.front();
  const GroupMap map = LoadGroupMap(map_work_dir, g, key, options);
  std::map<std::string, Tally> tallies;
  DirectMatchingReport report;
  report.features = SiftExtractorName(options.image.sift.extractor);
  for (const EvalGroup& pg : photos.groups) {
    for (const EvalImage& im : pg.images) {
      DirectMatchingPhoto row;
      LocalizePhoto(photos, im, map, map_work.dataset, options, &tallies, &row);
      // The truth is of another scene's frame: any success is wrong.
      for (auto& [name, a] : row.methods) {
        if (a.success) a.rotation_deg = a.translation = 1e9;
      }
      report.per_query.push_back(std::move(row));
    }
  }
  return report;
}

DirectMatchingReport RunDirectMatching(const EvalWork& work, const std::string& work_dir,
                                       const LiftingKey& key,
                                       const DirectMatchingOptions& options) {
  for (const std::string& name : options.rig_methods) {
    const MethodInfo& m = FindMethod(name);
    if (!m.multi || m.local_points) {
      Fail("direct matching: {} cannot localize a rig of photos (needs an m- method without +l)",
           name);
    }
  }
  std::map<std::string, Tally> tallies;
  DirectMatchingReport report;
  report.max_rotation_deg = options.max_rotation_deg;
  report.max_translation = options.max_translation;
  report.features = SiftExtractorName(options.image.sift.extractor);
  for (const EvalGroup& g : work.groups) {
    const auto t0 = std::chrono::steady_clock::now();
    const GroupMap map = LoadGroupMap(work_dir, g, key, options);
    std::vector<ImageQuery> photos;
    for (const EvalImage& im : g.images) {
      DirectMatchingPhoto row;
      ImageQuery q = LocalizePhoto(work, im, map, g.name, options, &tallies, &row);
      report.per_query.push_back(std::move(row));
      q.image = GreyImage{};  // the pixels are not needed any more
      photos.push_back(std::move(q));
    }
    if (g.has_rig && g.images.size() >= 2 && !options.rig_methods.empty()) {
      LocalizeRig(work, g, map, photos, options, &tallies, &report.per_rig);
    }
    LogProgress("[eval] direct matching, group {} ({:.1f} s)", g.name,
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  for (auto& [name, t] : tallies) {
    const double n = std::max<size_t>(1, t.rotation.size());
    DirectMatchingSummary& m = report.methods[name];
    m.queries = static_cast<int>(t.rotation.size());
    m.localized = t.localized;
    m.median_rotation_deg = Median(t.rotation);
    m.median_translation = Median(t.translation);
    m.mean_ms = {t.extract_ms / n, t.match_ms / n, t.ransac_ms / n, t.refine_ms / n};
    m.mean_solver_ms = t.solver_ms / n;
    m.mean_scoring_ms = t.scoring_ms / n;
    m.mean_local_optimization_ms = t.lo_ms / n;
    m.mean_iterations = t.iterations / n;
  }
  return report;
}

}  // namespace linecloud
