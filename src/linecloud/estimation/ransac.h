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
  int min_iterations = 10;     // draws at least
  int max_iterations = 10000;
  // Inliers the caller needs before it accepts a model (0: any). A search
  // that has not found so many stops once its draws would have found such a
  // model with `confidence` (see Ransac): the draws a photo of another place
  // costs are bounded by the matches it has, not by max_iterations.
  int min_support = 0;
  // A progressive run's competitor search (see Ransac): a model is a
  // competitor when it explains at least this share of the best model's
  // inlier count among the data the best model does not explain.
  double competitor_share = 0.5;
  // A progressive run's draws at most while no model has min_support inliers
  // (for a six-point sample; twice as many for each point less): PROSAC's
  // prefix grows to all the data within them (its T_N), so every datum has
  // been in samples by then (see Ransac).
  int no_support_draws = 500;
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
    if (!(competitor_share > 0 && competitor_share <= 1)) {
      Fail("RANSAC competitor share must be in (0, 1], got {}", competitor_share);
    }
    if (min_support < 0) Fail("RANSAC min_support must be >= 0, got {}", min_support);
    if (no_support_draws < 1)
      Fail("RANSAC no_support_draws must be >= 1, got {}", no_support_draws);
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
  int uniform_iterations = 0;  // of which uniform (all of a uniform run; none of a progressive one)
  int competitor_iterations = 0;  // of which the competitor search's (a progressive run's)
  int local_optimizations = 0;
  // The best model that a search among the data the final model leaves
  // unexplained found (0: none): its inliers over all the data, and those of
  // them the final model does not explain (a copy of the final pose, a degree
  // off, shares most of its inliers; a pose of a repeated structure explains
  // other matches).
  int runner_up_inliers = 0;
  int runner_up_own_inliers = 0;
  // Why the run stopped: "confidence" (enough iterations for an all-inlier
  // sample), "no_support" (enough draws to have found a model of
  // min_support inliers, none found), "max_iterations", "max_seconds" or
  // "stopped" (should_stop).
  const char* stop_reason = "confidence";
};

template <typename Model>
struct RansacResult {
  bool success = false;
  Model model{};
  std::vector<char> inlier_mask;
  // The competitor search's best model (stats.runner_up_inliers > 0).
  Model runner_up{};
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
//
// A uniform run stops by RANSAC's rule for its best model. A progressive run
// (Chum & Matas, "Matching with PROSAC", CVPR 2005) stops by PROSAC's own
// rule, evaluated per prefix of the ranking (sampler.h), then searches for a
// competitor: PROSAC again over the data its best model leaves unexplained,
// in the same order. PROSAC alone may stop on a coherent group of wrong
// matches among the best-ranked ones (a repeated facade element: castle-P19
// 9.8° off, 52 % inliers where the true pose has 76 %); the true pose then
// explains most of what that model leaves over, and is found there in a few
// samples. A competitor that explains more of all the data replaces the best
// (up to three rounds); otherwise it is reported as the runner-up, so that
// the caller can refuse a pose that another, different pose fits almost as
// well. The search gets as many draws as the one that found the best model
// (at least two samples' size), and stops early by PROSAC's rule or when a model with
// competitor_share of the best's inliers could not have been missed.
// (This replaces a uniform confirmation phase whose draws, for a 6-point
// solver at a third of inliers, took thousands of ~1 ms samples.)
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
  std::vector<int> sample(k);
  std::vector<char> mask;
  std::vector<Model> models;
  long total_models = 0;
  double solver_seconds = 0, scoring_seconds = 0, lo_seconds = 0;
  int iteration = 0;  // draws of every phase
  double next_progress = options.progress_interval_s;
  double next_stop_check = 0;
  const char* interrupted = nullptr;  // max_seconds or stopped

  // Time budget, progress and the caller's stop, checked before each draw.
  const auto interrupt = [&](int needed, int best_inliers) {
    if (options.max_seconds <= 0 && !options.progress && !options.should_stop) return false;
    const double elapsed = seconds_since(start);
    if (options.max_seconds > 0 && elapsed >= options.max_seconds) {
      interrupted = "max_seconds";
      return true;
    }
    if (options.should_stop && elapsed >= next_stop_check) {
      if (options.should_stop()) {
        interrupted = "stopped";
        return true;
      }
      next_stop_check = elapsed + 0.05;
    }
    if (options.progress && elapsed >= next_progress) {
      options.progress(iteration, needed, best_inliers, elapsed);
      next_progress = elapsed + options.progress_interval_s;
    }
    return false;
  };
  // A minimal sample's models, each scored on all the data against `bound`
  // and locally optimised when it beats it; `better(model, score, inliers)`
  // for each that does.
  const auto try_sample = [&](double bound, const auto& better) {
    const auto solve_start = Clock::now();
    estimator.generate_models(sample, &models);
    solver_seconds += seconds_since(solve_start);
    total_models += static_cast<long>(models.size());
    for (Model& model : models) {
      int inliers = 0;
      const auto score_start = Clock::now();
      double score = estimator.score_model(model, options.max_error, bound, &inliers);
      scoring_seconds += seconds_since(score_start);
      if (score >= bound) continue;
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
      bound = std::min(bound, better(model, score, inliers));
    }
  };
  // Draws that make missing a model of `inliers` among `pool` data unlikely.
  const auto draws_for = [&](int inliers, int pool) {
    return RequiredIterations(static_cast<double>(inliers) / std::max(1, pool), k,
                              options.confidence, options.max_iterations);
  };

  double best_score = std::numeric_limits<double>::infinity();
  int best_inliers = 0;
  const char* stop_reason = "max_iterations";
  if (!progressive) {
    // Uniform samples, RANSAC's own stopping rule for the best model.
    UniformSampler uniform(n, k, options.seed);
    int needed = options.max_iterations;
    for (; iteration < options.max_iterations; ++iteration) {
      if (iteration >= options.min_iterations && iteration >= needed) {
        stop_reason = "confidence";
        break;
      }
      if (interrupt(needed, best_inliers)) break;
      uniform.Sample(&sample);
      ++result.stats.uniform_iterations;
      try_sample(best_score, [&](const Model& model, double score, int inliers) {
        best_score = score;
        best_inliers = inliers;
        result.model = model;
        result.success = true;
        needed = draws_for(inliers, n);
        return score;
      });
      if (best_inliers < options.min_support &&
          iteration + 1 >= std::max(options.min_iterations, draws_for(options.min_support, n))) {
        ++iteration;
        stop_reason = "no_support";
        break;
      }
    }
  } else {
    // PROSAC over `order` (a ranking of data, best first), scoring on all the
    // data; `limit` draws at most. Returns the best model it found (if any)
    // with its score and inliers; `skip` data count as explained (outside).
    struct Found {
      bool any = false;
      Model model{};
      double score = std::numeric_limits<double>::infinity();
      int inliers = 0;
      const char* stop = "max_iterations";
    };
    const auto prosac = [&](std::span<const int> order, int limit, int wanted) {
      Found f;
      const int m = static_cast<int>(order.size());
      if (m < k) return f;
      // With a support to reach, the prefix grows to all the data within the
      // draws allowed without it (T_N), and the search ends there: a model
      // with that support among the best-ranked data would have been drawn,
      // and every datum has been in samples. (A uniform search for a model
      // of 60 inliers among 250 data needs ~48 000 six-point draws; photos
      // of another place spent 6 s in them.)
      // The cap is no_support_draws for a six-point sample and doubles for
      // each point less: a minimal solver's cost grows steeply with its
      // sample (p3P ~20 µs a draw, p6L ~600 µs), and a cheap one can search as
      // a uniform run would even when the ranking puts the wrong matches first.
      const int cap = static_cast<int>(std::min<int64_t>(
          options.max_iterations, int64_t{options.no_support_draws} << std::clamp(6 - k, 0, 10)));
      const int no_support_after =
          wanted > 0 ? std::min(draws_for(wanted, m), cap) : options.max_iterations;
      ProgressiveSampler sampler(order, k, options.seed + static_cast<uint64_t>(iteration),
                                 wanted > 0 ? no_support_after : options.max_iterations);
      ProgressiveStopping stopping(m, k, options.confidence);
      int needed = options.max_iterations;
      for (int drawn = 0; drawn < limit; ++drawn, ++iteration) {
        // PROSAC's rule, for a model with the support wanted: a model the
        // best-ranked data support by chance (EuRoC: 94 inliers of 1 134
        // matches, the true pose 1 064) does not end the search.
        if (iteration >= options.min_iterations && f.inliers >= wanted &&
            (stopping.Done() || drawn >= needed)) {
          f.stop = "confidence";
          return f;
        }
        // No model of `wanted` inliers found where it would have been.
        if (iteration >= options.min_iterations && f.inliers < wanted &&
            drawn >= no_support_after) {
          f.stop = "no_support";
          return f;
        }
        if (interrupt(iteration + needed - drawn, f.inliers)) return f;
        sampler.Sample(&sample);
        stopping.Record(sampler.subset_size(), sampler.last_with_newest());
        try_sample(f.score, [&](const Model& model, double score, int inliers) {
          f.any = true;
          f.model = model;
          f.score = score;
          f.inliers = inliers;
          estimator.inliers(model, options.max_error, &mask);
          stopping.Update(mask, order);
          sampler.LimitGrowth(stopping.best_prefix());
          needed = drawn + 1 + stopping.Remaining(sampler.subset_size(), options.max_iterations);
          return score;
        });
      }
      return f;
    };
    Found best = prosac(ranking, options.max_iterations, options.min_support);
    stop_reason = best.stop;
    const int first_search = iteration;
    if (best.any) {
      result.success = true;
      result.model = best.model;
      best_score = best.score;
      best_inliers = best.inliers;
    }
    // The competitor search (see above), only for a model the caller could accept.
    std::vector<int> rest;
    for (int round = 0; round < 3 && !interrupted && result.success &&
                        best_inliers >= std::max(options.min_support, k + 1);
         ++round) {
      estimator.inliers(result.model, options.max_error, &mask);
      rest.clear();
      for (const int i : ranking) {
        if (!mask[static_cast<size_t>(i)]) rest.push_back(i);
      }
      const int wanted = static_cast<int>(std::ceil(options.competitor_share * best_inliers));
      if (wanted > static_cast<int>(rest.size()) || static_cast<int>(rest.size()) < k) break;
      const int budget =
          std::min(std::max(2 * k, first_search), options.max_iterations - iteration);
      const int before = iteration;
      const Found rival = prosac(rest, budget, wanted);
      result.stats.competitor_iterations += iteration - before;
      if (!rival.any || rival.inliers < wanted) break;
      // Inliers of `a` that `b` does not explain.
      const auto own = [&](const Model& a, const Model& b) {
        std::vector<char> of_a, of_b;
        estimator.inliers(a, options.max_error, &of_a);
        estimator.inliers(b, options.max_error, &of_b);
        int count = 0;
        for (size_t i = 0; i < of_a.size(); ++i) count += of_a[i] && !of_b[i];
        return count;
      };
      if (rival.score < best_score) {  // explains more of all the data: the new best
        result.runner_up = result.model;
        result.stats.runner_up_inliers = best_inliers;
        result.stats.runner_up_own_inliers = own(result.model, rival.model);
        result.model = rival.model;
        best_score = rival.score;
        best_inliers = rival.inliers;
        continue;
      }
      if (rival.inliers > result.stats.runner_up_inliers) {
        result.runner_up = rival.model;
        result.stats.runner_up_inliers = rival.inliers;
        result.stats.runner_up_own_inliers = own(rival.model, result.model);
      }
      break;
    }
  }
  if (interrupted) stop_reason = interrupted;
  result.stats.iterations = iteration;
  const bool stopped = std::string_view(stop_reason) == "stopped";
  if (stopped) result.success = false;  // the caller stopped waiting: no model
  result.stats.stop_reason = stop_reason;
  result.stats.progressive = progressive;
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
