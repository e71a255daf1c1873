// Match scores as real photos give them, for synthetic queries: Lowe's ratio
// (best / second-best descriptor angle, matches kept below 0.8) of true
// inliers and of outliers, drawn from histograms measured on the direct
// matches of the Strecha photos ([image]: fountain-P11 and Herz-Jesus-P8,
// each query photo's SIFT matched to its group map, inliers by ground-truth
// reprojection within 4 px; 63 605 inliers, 3 506 outliers). Reproduce with
//   linecloud eval scores --work FOUNTAIN_WORK --work HERZ_WORK --out scores.json
// Inliers are spread over 0.2–0.8 with a mode near 0.5; outliers pile up
// just below the 0.8 cut (47 % in 0.75–0.8): the two overlap as on real
// images, so a ranking by ratio is informative but far from a classifier.
#pragma once

#include <random>

namespace linecloud {

// A ratio in [0, 0.8) drawn from the measured histogram of inliers or
// outliers (uniform within each 0.05-wide bin).
double DrawMatchRatio(bool inlier, std::mt19937_64& rng);

}  // namespace linecloud
