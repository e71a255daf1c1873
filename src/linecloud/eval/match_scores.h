// `linecloud eval scores`: how well a match's score tells inliers from
// outliers on real photos. Each query photo of a prepared dataset is matched
// straight to its group map's descriptors (the code path of `localize
// --image`); a match is a true inlier when its map point reprojects within
// `inlier_px` of the keypoint under the ground-truth pose. The histograms of
// Lowe's ratio (best / second-best descriptor angle) for inliers and outliers
// are what the synthetic benchmark's scores are drawn from ([fast-p6L]), and
// the inlier share among the best-ranked matches is what a progressive
// sampler (PROSAC) can exploit.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace linecloud {

struct MatchScoreOptions {
  std::vector<std::string> work_dirs;  // prepared by `eval prepare`
  std::string out;                     // JSON file
  double inlier_px = 4.0;
  int bins = 16;  // over [0, max_ratio]

  void Check() const;
};

// Writes and returns {"datasets": [...], "histogram": {"edges", "inliers",
// "outliers"}, "per_image": [...], "top_share": {...}}.
nlohmann::ordered_json RunMatchScores(const MatchScoreOptions& options);

}  // namespace linecloud
