// One RANSAC for every estimator: MSAC (truncated quadratic) scoring,
// adaptive stopping, local optimisation of each new best model, an explicit
// seed and statistics. Generic over an Estimator with
//
//   using Model = ...;
//   int num_data() const;
//   int sample_size() const;
//   // Every model of the minimal sample (indices into the data).
//   int generate_models(std::span<const int> sample, std::vector<Model>* out);
//   // Sum over the data of min(r², threshold²); counts inliers (r < threshold).
//   // May stop early and return any value >= `bound` once the sum reaches it.
//   double score_model(const Model& m, double threshold, double bound,
//                      int* num_inliers) const;
//   // Local optimisation on the inliers of `m` (may leave it unchanged).
//   void refine_model(Model* m, double threshold);
//   // Marks the inliers of `m`.
//   void inliers(const Model& m, double threshold, std::vector<char>* mask) const;
//
// Samples are uniform, or progressive (PROSAC, sampler.h) when the caller
// ranks the data by match quality.
//
// The structure follows PoseLib's ransac.h and COLMAP's loransac.h (Chum,
// Matas, Kittler, "Locally optimized RANSAC", DAGM 2003; Torr, Zisserman,
// "MLESAC", CVIU 2000).
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <string_view>
#include <limits>
#include <optional>
#include <span>
#include <vector>

#include "linecloud/estimation/sampler.h"
#include "linecloud/util/error.h"

namespace linecloud {

struct RansacOptions {
  double max_error = 4.0;      // inlier threshold, in the estimator's units (px)
  double confidence = 0.9999;  // probability of drawing one all-inlier sample
  // A progressive run's uniform phase (see Ransac): the probability that its
  // uniform samples alone would have found a model as good as the best.
  double uniform_phase_confidence = 0.99;
  int min_iterations = 10;  // floor of the uniform draws (see `enough` in Ransac)
  int max_iterations = 10000;
  bool local_optimization = true;
  uint64_t seed = 0;
  double max_seconds = 0;  // wall-clock budget; 0: none
  // With a ranking of the data (best first): PROSAC sampling and stopping
  // (sampler.h). Without one, or when false: uniform samples.
  bool progressive_sampling = true;
  // Called about every `progress_interval_s` seconds while the run lasts
  // (never for runs shorter than that): iterations so far, iterations the
  // current best model needs, its inliers, seconds elapsed.
  std::function<void(int, int, int, double)> progress;
  double progress_interval_s = 1.0;
  // Polled about every 50 ms while the run lasts: true ends it at once with
  // no model (stop_reason "stopped"), e.g. Python's Ctrl-C.
  std::function<bool()> should_stop;

  void Check() const {
    if (!(max_error > 0) || !std::isfinite(max_error)) {
      Fail("RANSAC threshold must be a positive number, got {}", max_error);
    }
    if (!(confidence > 0 && confidence < 1)) {
      Fail("RANSAC confidence must be in (0, 1), got {}", confidence);
    }
    if (!(uniform_phase_confidence > 0 && uniform_phase_confidence < 1)) {
      Fail("RANSAC uniform-phase confidence must be in (0, 1), got {}", uniform_phase_confidence);
    }
    if (!(max_seconds >= 0) || !std::isfinite(max_seconds)) {
      Fail("RANSAC time budget must be a non-negative number of seconds, got {}", max_seconds);
    }
    if (min_iterations < 0 || max_iterations < 1 || min_iterations > max_iterations) {
      Fail(
          "RANSAC iterations: min_iterations ({}) must be at least 0 and at most max_iterations "
          "({}), which must be at least 1",
          min_iterations, max_iterations);
    }
  }
};

struct RansacStats {
  int iterations = 0;
  int num_inliers = 0;
  double inlier_ratio = 0;
  double mean_solutions = 0;   // models per minimal sample
  double solver_us = 0;        // mean time of one generate_models call
  double ransac_ms = 0;        // whole run, local optimisation included
  double solver_ms = 0;        // of which minimal solvers,
  double scoring_ms = 0;       // scoring hypotheses,
  double lo_ms = 0;            // local optimisation (refine and re-score)
  bool progressive = false;    // PROSAC samples (a ranking was given)
  int uniform_iterations = 0;  // of which uniform (all of a uniform run; a progressive run's last)
  int local_optimizations = 0;
  // Why the run stopped: "confidence" (enough iterations for an all-inlier
  // sample), "max_iterations", "max_seconds" or "stopped" (should_stop).
  const char* stop_reason = "confidence";
};

template <typename Model>
struct RansacResult {
  bool success = false;
  Model model{};
  std::vector<char> inlier_mask;
  RansacStats stats;
};

// The indices of the set entries of an inlier mask (replaces *indices).
inline void InlierIndices(const std::vector<char>& mask, std::vector<int>* indices) {
  indices->clear();
  for (size_t i = 0; i < mask.size(); ++i) {
    if (mask[i]) indices->push_back(static_cast<int>(i));
  }
}

// `ranking`: optional, the data indices best first (a permutation of
// [0, num_data)), e.g. by Lowe's ratio; used with options.progressive_sampling.
template <typename Estimator>
RansacResult<typename Estimator::Model> Ransac(Estimator& estimator, const RansacOptions& options,
                                               std::span<const int> ranking = {}) {
  using Model = typename Estimator::Model;
  using Clock = std::chrono::steady_clock;
  const auto seconds_since = [](Clock::time_point t) {
    return std::chrono::duration<double>(Clock::now() - t).count();
  };
  options.Check();
  const auto start = Clock::now();
  RansacResult<Model> result;
  const int n = estimator.num_data();
  const int k = estimator.sample_size();
  if (!ranking.empty() && ranking.size() != static_cast<size_t>(n)) {
    Fail("RANSAC: a ranking of {} entries for {} data", ranking.size(), n);
  }
  if (n < k) return result;

  const bool progressive = options.progressive_sampling && !ranking.empty();
  UniformSampler uniform(n, k, options.seed);
  // Only progressive runs pay for their sampler and stopping rule (the rule's
  // table of I_min(n) costs about as much as a whole p3P run).
  std::optional<ProgressiveSampler> prosac;
  std::optional<ProgressiveStopping> stopping;
  if (progressive) {
    prosac.emplace(ranking, k, options.seed, options.max_iterations);
    stopping.emplace(n, k, options.confidence);
  }
  std::vector<int> sample(k);
  std::vector<char> mask;
  std::vector<Model> models;
  double best_score = std::numeric_limits<double>::infinity();
  int best_inliers = 0;
  long total_models = 0;
  double solver_seconds = 0, scoring_seconds = 0, lo_seconds = 0;
  int needed = options.max_iterations;
  int iteration = 0;
  double next_progress = options.progress_interval_s;
  double next_stop_check = 0;
  const char* stop_reason = "max_iterations";
  // A progressive run ends with a uniform phase. PROSAC's rule judges the best
  // model by the best-ranked data it explains, and its first samples all come
  // from the few best-ranked matches: a coherent group of wrong matches there
  // (a repeated facade element) gives a wrong model that explains every one of
  // them, and the rule stopped on it after three samples (castle-P19: 9.8°
  // off, 52 % inliers where the true pose has 76 %). So once PROSAC's rule
  // holds, uniform samples of all the data follow until RANSAC's own rule
  // holds for them alone: (1 − ε^k)^T ≤ 1 − uniform_phase_confidence, ε the
  // best model's inlier ratio over all the data — a uniform run's guarantee,
  // whatever the ranking did. min_iterations is a floor of the uniform draws.
  int uniform_drawn = 0;
  bool confirming = false;  // in the uniform phase
  // Uniform draws that make missing a model with `inliers` unlikely.
  const double uniform_confidence =
      progressive ? options.uniform_phase_confidence : options.confidence;
  const auto uniform_needed = [&](int inliers) {
    return RequiredIterations(static_cast<double>(inliers) / n, k, uniform_confidence,
                              options.max_iterations);
  };
  const auto enough = [&] {
    if (progressive && !confirming) {
      if (!stopping->Done()) return false;
      confirming = true;
      needed = uniform_needed(best_inliers);
    }
    return uniform_drawn >= options.min_iterations && uniform_drawn >= needed;
  };
  for (; iteration < options.max_iterations; ++iteration) {
    if (enough()) {
      stop_reason = "confidence";
      break;
    }
    if (options.max_seconds > 0 || options.progress || options.should_stop) {
      const double elapsed = seconds_since(start);
      if (options.max_seconds > 0 && elapsed >= options.max_seconds) {
        stop_reason = "max_seconds";
        break;
      }
      if (options.should_stop && elapsed >= next_stop_check) {
        if (options.should_stop()) {
          stop_reason = "stopped";
          break;
        }
        next_stop_check = elapsed + 0.05;
      }
      if (options.progress && elapsed >= next_progress) {
        options.progress(iteration, needed, best_inliers, elapsed);
        next_progress = elapsed + options.progress_interval_s;
      }
    }
    if (progressive && !confirming) {
      prosac->Sample(&sample);
      stopping->Record(prosac->subset_size(), prosac->last_with_newest());
    } else {
      uniform.Sample(&sample);
      ++uniform_drawn;
    }
    const auto solve_start = Clock::now();
    estimator.generate_models(sample, &models);
    solver_seconds += seconds_since(solve_start);
    total_models += static_cast<long>(models.size());
    for (Model& model : models) {
      int inliers = 0;
      const auto score_start = Clock::now();
      double score = estimator.score_model(model, options.max_error, best_score, &inliers);
      scoring_seconds += seconds_since(score_start);
      if (score >= best_score) continue;
      if (options.local_optimization && inliers > k) {
        const auto lo_start = Clock::now();
        Model refined = model;
        estimator.refine_model(&refined, options.max_error);
        int refined_inliers = 0;
        const double refined_score = estimator.score_model(
            refined, options.max_error, std::numeric_limits<double>::infinity(), &refined_inliers);
        ++result.stats.local_optimizations;
        if (refined_score < score) {
          model = refined;
          score = refined_score;
          inliers = refined_inliers;
        }
        lo_seconds += seconds_since(lo_start);
      }
      best_score = score;
      best_inliers = inliers;
      result.model = model;
      result.success = true;
      if (progressive && !confirming) {
        estimator.inliers(model, options.max_error, &mask);
        stopping->Update(mask, ranking);
        prosac->LimitGrowth(stopping->best_prefix());
        // For progress reports: PROSAC's samples still needed, then the uniform phase's.
        needed = iteration + 1 + stopping->Remaining(prosac->subset_size(), options.max_iterations);
      } else {
        needed = uniform_needed(inliers);
      }
    }
  }
  result.stats.iterations = iteration;
  const bool stopped = std::string_view(stop_reason) == "stopped";
  if (stopped) result.success = false;  // the caller stopped waiting: no model
  if (!stopped && enough()) stop_reason = "confidence";
  result.stats.stop_reason = stop_reason;
  result.stats.progressive = progressive;
  result.stats.uniform_iterations = uniform_drawn;
  if (result.success) {
    estimator.inliers(result.model, options.max_error, &result.inlier_mask);
    result.stats.num_inliers = best_inliers;
    result.stats.inlier_ratio = static_cast<double>(best_inliers) / n;
  }
  if (iteration > 0) {
    result.stats.mean_solutions = static_cast<double>(total_models) / iteration;
    result.stats.solver_us = 1e6 * solver_seconds / iteration;
  }
  result.stats.solver_ms = 1e3 * solver_seconds;
  result.stats.scoring_ms = 1e3 * scoring_seconds;
  result.stats.lo_ms = 1e3 * lo_seconds;
  result.stats.ransac_ms = 1e3 * seconds_since(start);
  return result;
}

}  // namespace linecloud
