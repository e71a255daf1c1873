// Minimal-sample generators for the generic RANSAC (ransac.h) and the
// stopping rule that goes with each.
//
// UniformSampler: k distinct indices of [0, n), every subset equally likely;
// RANSAC stops once an all-inlier sample has been drawn with the requested
// confidence (Fischler, Bolles, CACM 1981).
//
// ProgressiveSampler: PROSAC's sampling (Chum, Matas, "Matching with PROSAC —
// progressive sample consensus", CVPR 2005). The data are ranked by match
// quality (e.g. Lowe's ratio); samples are drawn from a growing prefix U_n of
// the ranking, so that the best-ranked correspondences are tried first, and
// the schedule reaches all the data after `growth_max_samples` samples (then
// it is plain RANSAC). With T_N = growth_max_samples, the expected number of
// samples of U_n drawn by RANSAC on all data is
//     T_n = T_N · C(n, k) / C(N, k),   T_{n+1} = T_n · (n + 1) / (n + 1 − k),
// and U_n is used for T'_n = Σ ⌈T_{i+1} − T_i⌉ samples; while t ≤ T'_n a sample
// is the newest point u_n and k − 1 points of U_{n−1}, afterwards k points of
// U_n.
//
// ProgressiveStopping: when to stop sampling. RANSAC's own rule assumes
// uniform samples of all the data; PROSAC's samples are not (its maximality
// rule credits a prefix with every sample drawn inside it, most of them from
// its top; with an adversarial ranking it stopped on a line with 62 of 120
// inliers, and ransac_test.cc checks that ours does not). Ours keeps RANSAC's
// meaning exactly for any sampler: with the best model's inliers taken as the
// true ones, the probability that no sample drawn so far was all-inlier is
//     P_miss = Π_t (1 − p_t),
// p_t the probability that sample t, drawn from the prefix U_n(t) (or its
// newest point and k − 1 of U_n(t)−1), is all-inlier:
//     p = Π_{j<k} (I_n − j) / (n − j)      (k of U_n),
// and RANSAC stops once P_miss ≤ 1 − confidence. Each p_t is recomputed from
// the sample counts per prefix when the best model changes. A prefix whose
// support could be chance (PROSAC's non-randomness test: fewer than
// I_min(n) inliers, the binomial tail of β = 5 % chance agreement at ψ = 5 %;
// a model always "explains" its own sample) contributes p = 0.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <span>
#include <vector>

#include "linecloud/util/error.h"

namespace linecloud {

// Iterations needed to draw an all-inlier sample with `confidence`.
inline int RequiredIterations(double inlier_ratio, int sample_size, double confidence,
                              int max_iterations) {
  if (inlier_ratio <= 0) return max_iterations;
  const double all_inliers = std::pow(inlier_ratio, sample_size);
  if (all_inliers >= 1) return 0;
  const double n = std::log(1 - confidence) / std::log1p(-all_inliers);
  return n >= max_iterations ? max_iterations : static_cast<int>(std::ceil(n));
}

// Writes `count` distinct indices of [0, pool) to sample[0, count) (count is
// tiny: rejection is cheaper than shuffling).
inline void DrawDistinct(int pool, int count, std::mt19937_64& rng, std::vector<int>* sample) {
  for (int i = 0; i < count; ++i) {
    int candidate;
    do {
      candidate = static_cast<int>(rng() % static_cast<uint64_t>(pool));
    } while (std::find(sample->begin(), sample->begin() + i, candidate) != sample->begin() + i);
    (*sample)[static_cast<size_t>(i)] = candidate;
  }
}

class UniformSampler {
 public:
  UniformSampler(int num_data, int sample_size, uint64_t seed)
      : n_(num_data), k_(sample_size), rng_(seed) {}

  void Sample(std::vector<int>* sample) {
    sample->resize(static_cast<size_t>(k_));
    DrawDistinct(n_, k_, rng_, sample);
  }

 private:
  int n_, k_;
  std::mt19937_64 rng_;
};

class ProgressiveSampler {
 public:
  // `ranking`: the data indices, best first (a permutation of [0, N)); it must
  // outlive the sampler (no copy is made).
  ProgressiveSampler(std::span<const int> ranking, int sample_size, uint64_t seed,
                     int growth_max_samples)
      : ranking_(ranking),
        k_(sample_size),
        rng_(seed),
        subset_(sample_size),
        limit_(static_cast<int>(ranking.size())) {
    if (sample_size < 1 || ranking.size() < static_cast<size_t>(sample_size)) {
      Fail("progressive sampling: {} ranked data for samples of {}", ranking.size(), sample_size);
    }
    // T_k = T_N Π_{i<k} (k − i) / (N − i).
    const int n = static_cast<int>(ranking.size());
    t_n_ = std::max(1, growth_max_samples);
    for (int i = 0; i < k_; ++i) t_n_ *= static_cast<double>(k_ - i) / (n - i);
    t_prime_ = 1;
  }

  void Sample(std::vector<int>* sample) {
    ++drawn_;
    const int n = static_cast<int>(ranking_.size());
    if (drawn_ > t_prime_ && subset_ < std::min(n, limit_)) {
      // U_{n+1}: T'_{n+1} = T'_n + ⌈T_{n+1} − T_n⌉.
      const double next = t_n_ * (subset_ + 1) / (subset_ + 1 - k_);
      t_prime_ += static_cast<int64_t>(std::ceil(next - t_n_));
      t_n_ = next;
      ++subset_;
    }
    sample->resize(static_cast<size_t>(k_));
    // While t ≤ T'_n: u_n and k − 1 of U_{n−1}; afterwards k of U_n.
    with_newest_ = drawn_ <= t_prime_;
    const bool with_newest = with_newest_;
    const int pool = with_newest ? subset_ - 1 : subset_;
    DrawDistinct(pool, with_newest ? k_ - 1 : k_, rng_, sample);
    if (with_newest) (*sample)[static_cast<size_t>(k_ - 1)] = subset_ - 1;
    for (int& s : *sample) s = ranking_[static_cast<size_t>(s)];
  }

  // PROSAC: the prefix stops growing at n* (never shrinks).
  void LimitGrowth(int top) { limit_ = std::max(top, subset_); }
  // The prefix the last sample came from, and whether it held u_n.
  int subset_size() const { return subset_; }
  bool last_with_newest() const { return with_newest_; }
  std::span<const int> ranking() const { return ranking_; }

 private:
  std::span<const int> ranking_;
  int k_;
  std::mt19937_64 rng_;
  int subset_;           // n: the sampled prefix U_n
  int64_t drawn_ = 0;    // t (64 bits: T'_n may pass 2^31 for huge caps)
  double t_n_ = 0;       // T_n
  int64_t t_prime_ = 1;  // T'_n
  bool with_newest_ = true;
  int limit_;  // n*: the prefix does not grow beyond it
};

class ProgressiveStopping {
 public:
  static constexpr double kBeta = 0.05;  // chance support of a wrong model
  static constexpr double kPsi = 0.05;   // level of the non-randomness test

  ProgressiveStopping(int num_data, int sample_size, double confidence)
      : n_(num_data),
        k_(sample_size),
        log_eta_(std::log(1 - confidence)),
        counts_(2 * (static_cast<size_t>(num_data) + 1), 0) {
    min_inliers_.resize(static_cast<size_t>(n_) + 1);
    for (int n = 0; n <= n_; ++n) min_inliers_[static_cast<size_t>(n)] = ComputeMinInliers(n);
  }

  // One more sample, drawn from U_n (with_newest: u_n and k − 1 of U_{n−1}).
  void Record(int subset, bool with_newest) {
    const size_t slot = Slot(subset, with_newest);
    if (counts_[slot]++ == 0) used_slots_.push_back(static_cast<int>(slot));
    if (has_model_) log_miss_ += LogMiss(subset, with_newest);
  }

  // A new best model with this inlier mask (indexed by datum).
  void Update(const std::vector<char>& inlier_mask, std::span<const int> ranking) {
    has_model_ = true;
    ranking_inlier_.assign(static_cast<size_t>(n_) + 1, 0);
    prefix_inliers_.assign(static_cast<size_t>(n_) + 1, 0);
    for (int n = 1; n <= n_; ++n) {
      ranking_inlier_[static_cast<size_t>(n)] =
          inlier_mask[static_cast<size_t>(ranking[static_cast<size_t>(n - 1)])] != 0;
      prefix_inliers_[static_cast<size_t>(n)] =
          prefix_inliers_[static_cast<size_t>(n - 1)] + ranking_inlier_[static_cast<size_t>(n)];
    }
    // n*: the prefix whose samples are most likely all-inlier (largest p,
    // compared without logarithms; ties keep the shorter). log(1 − p) only
    // for the prefixes that samples came from (a handful).
    log_miss_ = 0;
    best_prefix_ = n_;
    double best = 0;
    for (int n = k_; n <= n_; ++n) {
      const double p = AllInlier(n, false);
      if (p > best) {
        best = p;
        best_prefix_ = n;
      }
    }
    for (const int slot : used_slots_) {
      log_miss_ += counts_[static_cast<size_t>(slot)] * LogMiss(slot / 2, slot % 2 != 0);
    }
  }

  bool Done() const { return has_model_ && log_miss_ <= log_eta_; }
  // n*: the prefix whose samples are most likely all-inlier (all the data
  // when no prefix is significant).
  int best_prefix() const { return best_prefix_; }

  // Samples still needed if they keep coming from U_n (for progress reports).
  int Remaining(int subset, int max_iterations) const {
    if (Done()) return 0;
    const double per_sample = has_model_ ? LogMiss(subset, false) : 0;
    if (!(per_sample < 0)) return max_iterations;
    const double r = (log_eta_ - log_miss_) / per_sample;
    return r >= max_iterations ? max_iterations : static_cast<int>(std::ceil(r));
  }

  // I_min(n): the fewest inliers among the top n that chance (each datum
  // agreeing with a wrong model with probability β, beyond the k of its
  // sample) reaches with probability below ψ; n + 1 when none is that rare.
  int MinInliers(int n) const { return min_inliers_[static_cast<size_t>(n)]; }

 private:
  size_t Slot(int subset, bool with_newest) const {
    return 2 * static_cast<size_t>(subset) + (with_newest ? 1 : 0);
  }

  // p: the probability that a sample from U_n (or u_n + k − 1 of U_{n−1}) is
  // all-inlier; 0 when U_n's support could be chance.
  double AllInlier(int n, bool with_newest) const {
    if (n < k_ || prefix_inliers_[static_cast<size_t>(n)] < MinInliers(n)) return 0;
    int pool = n, inliers = prefix_inliers_[static_cast<size_t>(n)], draws = k_;
    if (with_newest) {
      if (!ranking_inlier_[static_cast<size_t>(n)]) return 0;
      pool = n - 1;
      inliers -= 1;
      draws = k_ - 1;
    }
    double p = 1;
    for (int j = 0; j < draws; ++j) p *= static_cast<double>(inliers - j) / (pool - j);
    return p > 0 ? p : 0;
  }

  // log(1 − p) of such a sample.
  double LogMiss(int n, bool with_newest) const {
    const double p = AllInlier(n, with_newest);
    if (!(p > 0)) return 0;
    return p >= 1 ? -std::numeric_limits<double>::infinity() : std::log1p(-p);
  }

  int ComputeMinInliers(int n) const {
    const int m = n - k_;  // data that can agree by chance
    if (m <= 0) return n + 1;
    if (m > 60) {
      // Normal approximation of the binomial tail.
      constexpr double kZ = 1.6449;  // one-sided 5 %
      return k_ + static_cast<int>(std::ceil(kBeta * m + kZ * std::sqrt(kBeta * (1 - kBeta) * m)));
    }
    // Exact: the smallest j with P(Bin(m, β) ≥ j) < ψ.
    double pmf = std::pow(1 - kBeta, m);  // P(0)
    double cdf = pmf;
    for (int j = 1; j <= m; ++j) {
      if (1 - cdf < kPsi) return k_ + j;
      pmf *= (static_cast<double>(m - j + 1) / j) * kBeta / (1 - kBeta);
      cdf += pmf;
    }
    return n + 1;
  }

  int n_, k_;
  double log_eta_;
  bool has_model_ = false;
  double log_miss_ = 0;
  int best_prefix_ = 0;
  std::vector<int> counts_;      // samples per (prefix, with_newest)
  std::vector<int> used_slots_;  // the slots of counts_ that are not zero
  std::vector<int> min_inliers_;
  std::vector<char> ranking_inlier_;  // [n]: the n-th ranked datum is an inlier
  std::vector<int> prefix_inliers_;
};

}  // namespace linecloud
