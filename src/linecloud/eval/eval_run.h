// `linecloud eval run`: the 16 methods on the correspondences `eval prepare`
// stored, against each group's point map and its lifted line cloud, initial
// and refined; report.json, report.md (the paper's Table 2 layout) and PNG
// plots (Figs. 5, 7 and 8 of Speciale et al., CVPR 2019).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "linecloud/eval/direct_matching.h"
#include "linecloud/eval/eval_report.h"
#include "linecloud/eval/eval_work.h"
#include "linecloud/lifting/key.h"
#include "linecloud/privacy/map_lifting.h"

namespace linecloud {

struct EvalRunOptions {
  std::string work_dir;
  std::string out_dir;
  std::vector<std::string> methods;  // empty: all 16
  MapLifting lifting;                // how the maps are lifted (lift's --sparsify, ...)
  double noise_px = 0.0;             // Gaussian noise added to the query pixels
  double threshold_px = 4.0;         // RANSAC inlier threshold, every method
  uint64_t seed = 1;
  // Fig. 7: map densities (share dropped) swept for the density plot; empty: no sweep.
  std::vector<double> density_sweep = {0.0, 0.5, 0.75, 0.9, 0.95};
  // Fig. 8: synthetic pixel-noise levels; empty: no sweep.
  std::vector<double> noise_sweep = {0.0, 1.0, 2.0, 3.0, 4.0, 5.0};
  int noise_sweep_queries = 10;  // synthetic queries per method and level
  // The deployable protocol beside the paper's: query images' own features
  // matched to the map's descriptors (direct_matching.h).
  bool direct_matching = true;
  // The photos' feature extractor there (opencv, or colmap: COLMAP's own).
  SiftExtractor features = SiftOptions{}.extractor;
  // Shared by runs that match the same photos to other maps (eval privacy):
  // each photo's SIFT is extracted once.
  std::shared_ptr<ExtractedPhotos> extracted_photos;

  void Check() const;
};

// Runs everything and writes report.json, report.md and the figures into out_dir; returns the
// report.
EvalReport RunEvaluation(const EvalRunOptions& options);

// WORK/prepared.json; throws Error naming it when missing or malformed.
EvalWork ReadPreparedWork(const std::string& work_dir);
// The evaluation's one permanent key of a work directory (WORK/lifting.key,
// created on first use).
LiftingKey EvalLiftingKey(const std::string& work_dir);

}  // namespace linecloud
