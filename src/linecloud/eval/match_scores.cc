#include "linecloud/util/log.h"
#include "linecloud/eval/match_scores.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <fmt/format.h>

#include "linecloud/eval/direct_matching.h"
#include "linecloud/eval/eval_run.h"
#include "linecloud/features/matching.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/pipeline/image_query.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

using ojson = nlohmann::ordered_json;

// The matches of one photo with their ratio and whether the ground truth
// makes them inliers.
std::vector<ScoredMatch> ScoreImageMatches(const EvalWork& work, const EvalImage& im,
                                           const Reconstruction& model, const MapDescriptors& map,
                                           double inlier_px) {
  const std::string path = JoinPaths(JoinPaths(work.dataset_dir, "images"), im.name);
  const Camera& camera = work.cameras.at(im.camera_id);
  const ImageQuery q = QueryFromImage(path, camera, map, {});
  std::vector<ScoredMatch> out;
  for (size_t k = 0; k < q.matches.size(); ++k) {
    const QueryObservation& obs = q.query.observations[k];
    const Eigen::Vector3d p = im.cam_from_world * model.points3D.at(obs.id).xyz;
    const bool inlier = p.z() > 0 && (camera.ImgFromCam(p) - obs.xy).norm() < inlier_px;
    out.push_back({q.matches[k].ratio, inlier});
  }
  return out;
}

std::vector<TopShare> TopShares(const std::vector<ScoredImage>& images) {
  std::vector<TopShare> shares;
  for (const int top : {10, 25, 50, 100, 200, 500}) {
    double sum = 0;
    int counted = 0;
    for (const ScoredImage& image : images) {
      std::vector<ScoredMatch> m = image.matches;
      if (m.size() < static_cast<size_t>(top)) continue;
      std::stable_sort(m.begin(), m.end(), [](const ScoredMatch& a, const ScoredMatch& b) {
        return a.ratio < b.ratio;
      });
      int in = 0;
      for (int i = 0; i < top; ++i) in += m[static_cast<size_t>(i)].inlier;
      sum += static_cast<double>(in) / top;
      ++counted;
    }
    if (counted > 0) shares.push_back({top, counted, sum / counted});
  }
  return shares;
}

}  // namespace

void MatchScoreOptions::Check() const {
  if (work_dirs.empty()) Fail("eval scores: give at least one --work directory");
  if (out.empty()) Fail("eval scores: --out is required");
  if (!(inlier_px > 0) || !std::isfinite(inlier_px)) Fail("eval scores: --inlier-px must be > 0");
  if (bins < 2 || bins > 1000) Fail("eval scores: --bins must be in [2, 1000]");
}

MatchScoreReport SummarizeMatchScores(const std::vector<ScoredImage>& images, double max_ratio,
                                      int bins, double inlier_px) {
  if (bins < 1 || !(max_ratio > 0)) Fail("eval scores: {} bins over [0, {}]", bins, max_ratio);
  MatchScoreReport r;
  r.inlier_px = inlier_px;
  for (int b = 0; b <= bins; ++b) r.edges.push_back(max_ratio * b / bins);
  r.inliers.assign(static_cast<size_t>(bins), 0);
  r.outliers.assign(static_cast<size_t>(bins), 0);
  for (const ScoredImage& image : images) {
    if (r.datasets.empty() || r.datasets.back() != image.dataset)
      r.datasets.push_back(image.dataset);
    size_t inliers = 0;
    for (const ScoredMatch& s : image.matches) {
      const int b = std::clamp(static_cast<int>(s.ratio / max_ratio * bins), 0, bins - 1);
      (s.inlier ? r.inliers : r.outliers)[static_cast<size_t>(b)]++;
      inliers += s.inlier;
    }
    r.per_image.push_back({image.dataset, image.group, image.image, image.matches.size(), inliers});
  }
  r.top_shares = TopShares(images);
  return r;
}

ojson ToJson(const MatchScoreReport& r) {
  ojson top = ojson::object();
  for (const TopShare& s : r.top_shares)
    top[fmt::format("{}", s.top)] = {{"images", s.images}, {"inlier_share", s.inlier_share}};
  ojson per_image = ojson::array();
  for (const ImageMatchCount& c : r.per_image) {
    per_image.push_back({{"dataset", c.dataset},
                         {"group", c.group},
                         {"image", c.image},
                         {"matches", c.matches},
                         {"inliers", c.inliers},
                         {"inlier_ratio", c.matches ? double(c.inliers) / c.matches : 0.0}});
  }
  return {{"datasets", r.datasets},
          {"inlier_px", r.inlier_px},
          {"histogram",
           {{"score", "Lowe ratio (best / second-best descriptor angle)"},
            {"edges", r.edges},
            {"inliers", r.inliers},
            {"outliers", r.outliers}}},
          {"top_share", top},
          {"per_image", per_image}};
}

MatchScoreReport RunMatchScores(const MatchScoreOptions& options) {
  options.Check();
  RefuseOutputOverInputs(options.out, options.work_dirs, "--out");
  std::vector<ScoredImage> images;
  std::vector<std::string> datasets;
  for (const std::string& work_dir : options.work_dirs) {
    const EvalWork work = ReadPreparedWork(work_dir);
    datasets.push_back(work.dataset);
    for (const EvalGroup& g : work.groups) {
      const Reconstruction model = ReadColmapModel(JoinPaths(work_dir, g.map_dir));
      std::vector<std::string> names;
      for (const EvalImage& im : g.images) names.push_back(im.name);
      const MapDescriptors map =
          MapDescriptorsExcluding(model, JoinPaths(work_dir, "colmap/database.db"), names);
      for (const EvalImage& im : g.images) {
        ScoredImage image{work.dataset, g.name, im.name,
                          ScoreImageMatches(work, im, model, map, options.inlier_px)};
        LogProgress("[scores] {} {}: {} matches, {} inliers", work.dataset, im.name,
                    image.matches.size(),
                    std::count_if(image.matches.begin(), image.matches.end(),
                                  [](const ScoredMatch& s) { return s.inlier; }));
        images.push_back(std::move(image));
      }
    }
  }
  MatchScoreReport report = SummarizeMatchScores(images, DescriptorMatchOptions{}.max_ratio,
                                                 options.bins, options.inlier_px);
  report.datasets = datasets;
  WriteFileAtomically(options.out, [&](std::ostream& os) { os << ToJson(report).dump(2) << "\n"; });
  return report;
}

}  // namespace linecloud
