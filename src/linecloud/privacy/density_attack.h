// The line-cloud density attack (Chelani, Kahl, Sattler, "How Privacy-
// Preserving are Line Clouds? Recovering Scene Details from 3D Lines",
// CVPR 2021): what an attacker who holds only a `.lcm` recovers.
//
// A map's points lie on surfaces, so the lines of a point's spatial neighbours
// pass close to it. For line i, the points of line i closest to each of its
// K nearest lines (by line–line distance) are votes t_ij along line i; they
// cluster around the secret point, and a robust peak of the votes estimates
// it. Refinement rounds then use the current estimates P̂: the neighbours of
// line i become the lines both among the K' estimates nearest to line i
// (line-to-point) and among the K' lines nearest to P̂_i (point-to-line) when
// they share more than `min_shared`, else the former; the votes are taken
// again from those lines.
//
// The peak (our own formulation of the paper's Kuiper-statistic clustering):
// drop the `trimmed_votes` extreme votes at each end; then, on a histogram of
// the remaining votes over their range, find the interval [a, b] whose share
// of votes exceeds its share of the range by the most (a maximum-sum
// subarray of the empirical-minus-uniform CDF increments); keep the votes
// inside; repeat while that excess is at least `min_excess`. The estimate is
// the median of the votes kept.
//
// Searches are exact brute force over all pairs (line_neighbours.h) up to
// `exact_search_lines` lines; beyond, through a grid of the scene's box
// (NeighbourGrid), exact within radii that hold the k nearest of 95 % of
// sampled lines (× 1.5), for pairs meeting inside the box where the sampled
// lines' estimates fall. On `threads` threads. Defaults are the published ones.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "linecloud/lifting/line_cloud.h"

namespace linecloud {

struct DensityAttackOptions {
  // K of the coarse step; 0: min(500, 5 % of the lines), as published.
  int line_neighbours = 0;
  int refine_rounds = 2;        // the published code suggests 2 or 3
  int refine_neighbours = 100;  // K' of the line-to-point and point-to-line sets
  int min_shared = 10;          // more shared neighbours than this: use the intersection
  int histogram_bins = 500;
  int trimmed_votes = 5;    // dropped at each end before the peak search
  double min_excess = 0.3;  // the peak search continues while the excess is at least this
  int threads = 0;          // 0: all cores
  // Up to this many lines every pair is compared (n², the published search);
  // beyond, the grid search (seeded rooms on 2 cores: 182 531 lines in 45 s,
  // 1 010 364 in 274 s).
  int exact_search_lines = 200000;
  // Time budget of the whole attack (0: none). The exact search's cost grows
  // as n² (every line against every line, 1 + 2 x refine_rounds passes):
  // 100 000 lines take ~40 s on 2 cores, 772 000 lines would take 40 min. When the budget runs out
  // the attack stops and throws Error with the projected total time.
  double max_seconds = 0;
  // Stage name, rows done, rows in the stage; from the calling thread.
  std::function<void(const std::string&, size_t, size_t)> progress;

  void Check() const;  // throws Error naming the option
};

struct DensityAttackResult {
  // One per line of the cloud, in its order: the recovered point (on the line).
  std::vector<Eigen::Vector3d> points;
  // Share of the line's votes inside its final peak (0: the line had no votes,
  // e.g. all its neighbours parallel to it; its estimate is its anchor).
  std::vector<float> peak_share;
  size_t lines_without_votes = 0;
  int line_neighbours = 0;  // the K used
  // The grid search: its line-to-line radius (0: exact search), and the
  // lines that found fewer than K neighbours within it.
  double search_radius = 0;
  size_t lines_short_of_neighbours = 0;
  double seconds = 0;
};

// Throws Error when the cloud has fewer than 10 lines.
DensityAttackResult RunDensityAttack(const LineCloud& cloud, const DensityAttackOptions& options);

// The robust peak of 1-D votes (see above). `votes` is reordered. Returns NaN
// for no votes; `share` (optional) receives the share of votes in the peak.
double VotePeak(std::vector<double>* votes, int bins, int trimmed, double min_excess,
                double* share = nullptr);

}  // namespace linecloud
