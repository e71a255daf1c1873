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

struct ScoredMatch {
  float ratio = 0;
  bool inlier = false;
};

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

ojson TopShares(const std::vector<std::vector<ScoredMatch>>& images) {
  ojson shares = ojson::object();
  for (const int top : {10, 25, 50, 100, 200, 500}) {
    double sum = 0;
    int counted = 0;
    for (std::vector<ScoredMatch> m : images) {
      if (m.size() < static_cast<size_t>(top)) continue;
      std::stable_sort(m.begin(), m.end(), [](const ScoredMatch& a, const ScoredMatch& b) {
        return a.ratio < b.ratio;
      });
      int in = 0;
      for (int i = 0; i < top; ++i) in += m[static_cast<size_t>(i)].inlier;
      sum += static_cast<double>(in) / top;
      ++counted;
    }
    if (counted > 0)
      shares[fmt::format("{}", top)] = {{"images", counted}, {"inlier_share", sum / counted}};
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

ojson RunMatchScores(const MatchScoreOptions& options) {
  options.Check();
  const double max_ratio = DescriptorMatchOptions{}.max_ratio;
  std::vector<double> edges;
  for (int b = 0; b <= options.bins; ++b) edges.push_back(max_ratio * b / options.bins);
  std::vector<long> hist_in(static_cast<size_t>(options.bins), 0);
  std::vector<long> hist_out(static_cast<size_t>(options.bins), 0);
  std::vector<std::vector<ScoredMatch>> all_images;
  ojson per_image = ojson::array(), datasets = ojson::array();
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
        std::vector<ScoredMatch> m = ScoreImageMatches(work, im, model, map, options.inlier_px);
        int inliers = 0;
        for (const ScoredMatch& s : m) {
          const int b =
              std::clamp(static_cast<int>(s.ratio / max_ratio * options.bins), 0, options.bins - 1);
          (s.inlier ? hist_in : hist_out)[static_cast<size_t>(b)]++;
          inliers += s.inlier;
        }
        per_image.push_back({{"dataset", work.dataset},
                             {"group", g.name},
                             {"image", im.name},
                             {"matches", m.size()},
                             {"inliers", inliers},
                             {"inlier_ratio", m.empty() ? 0.0 : double(inliers) / m.size()}});
        LogProgress("[scores] {} {}: {} matches, {} inliers", work.dataset, im.name, m.size(),
                    inliers);
        all_images.push_back(std::move(m));
      }
    }
  }
  ojson report;
  report["datasets"] = datasets;
  report["inlier_px"] = options.inlier_px;
  report["histogram"] = {{"score", "Lowe ratio (best / second-best descriptor angle)"},
                         {"edges", edges},
                         {"inliers", hist_in},
                         {"outliers", hist_out}};
  report["top_share"] = TopShares(all_images);
  report["per_image"] = per_image;
  WriteFileAtomically(options.out, [&](std::ostream& os) { os << report.dump(2) << "\n"; });
  return report;
}

}  // namespace linecloud
