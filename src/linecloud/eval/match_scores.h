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

// One match of a query photo: its Lowe ratio, and whether the ground truth makes it an inlier.
struct ScoredMatch {
  float ratio = 0;
  bool inlier = false;
};

struct ScoredImage {
  std::string dataset, group, image;
  std::vector<ScoredMatch> matches;
};

// The inlier share among an image's `top` best-ranked matches, averaged over
// the images with at least `top` matches.
struct TopShare {
  int top = 0;
  int images = 0;
  double inlier_share = 0;
};

struct ImageMatchCount {
  std::string dataset, group, image;
  size_t matches = 0, inliers = 0;
};

struct MatchScoreReport {
  std::vector<std::string> datasets;
  double inlier_px = 0;
  std::vector<double> edges;            // bins + 1 ratios over [0, max_ratio]
  std::vector<long> inliers, outliers;  // matches per bin
  std::vector<TopShare> top_shares;     // top 10, 25, 50, 100, 200, 500
  std::vector<ImageMatchCount> per_image;
};

// The histograms and top shares of scored images (ratios over [0, max_ratio] in `bins` bins).
MatchScoreReport SummarizeMatchScores(const std::vector<ScoredImage>& images, double max_ratio,
                                      int bins, double inlier_px);

// {"datasets", "inlier_px", "histogram": {"score", "edges", "inliers", "outliers"},
// "top_share": {"10": {"images", "inlier_share"}, ...}, "per_image": [...]}.
nlohmann::ordered_json ToJson(const MatchScoreReport& report);

// Scores every query photo of the work directories; writes `out` (ToJson).
MatchScoreReport RunMatchScores(const MatchScoreOptions& options);

}  // namespace linecloud
