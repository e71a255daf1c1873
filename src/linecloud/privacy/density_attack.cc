#include "linecloud/privacy/density_attack.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>

#include "linecloud/privacy/line_neighbours.h"
#include "linecloud/util/error.h"
#include "linecloud/util/parallel.h"

namespace linecloud {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr size_t kMinLines = 10;

// Per-thread scratch.
struct Scratch {
  std::vector<float> d2;
  SelectBuffers select;
  std::vector<uint32_t> a, b, shared;
  std::vector<double> votes;
};

Eigen::Vector3d MedianAnchor(const LineCloud& cloud) {
  std::vector<double> c[3];
  for (const PluckerLine& l : cloud.lines) {
    const Eigen::Vector3d p = l.v.cross(l.w) / l.v.squaredNorm();
    for (int k = 0; k < 3; ++k) c[k].push_back(p[k]);
  }
  Eigen::Vector3d m;
  for (int k = 0; k < 3; ++k) {
    std::nth_element(c[k].begin(), c[k].begin() + c[k].size() / 2, c[k].end());
    m[k] = c[k][c[k].size() / 2];
  }
  return m;
}

// Votes along line i: the parameters of its points closest to lines `js`.
void Votes(const LineArrays& a, size_t i, const std::vector<uint32_t>& js,
           std::vector<double>* votes) {
  votes->clear();
  const Eigen::Vector3d& vi = a.v[i];
  for (const uint32_t j : js) {
    const Eigen::Vector3d r = a.q[j] - a.q[i];
    const double c = vi.dot(a.v[j]);
    const double den = 1.0 - c * c;
    if (den < 1e-4) continue;  // near-parallel: no crossing to speak of
    votes->push_back((r.dot(vi) - c * r.dot(a.v[j])) / den);
  }
}

std::function<void(size_t, size_t)> StageProgress(const DensityAttackOptions& o,
                                                  const std::string& stage) {
  if (!o.progress) return nullptr;
  return [&o, stage](size_t done, size_t total) { o.progress(stage, done, total); };
}

}  // namespace

void DensityAttackOptions::Check() const {
  if (line_neighbours < 0) Fail("attack: line neighbours must be >= 0 (0: the published default)");
  if (refine_rounds < 0 || refine_rounds > 20) Fail("attack: refine rounds must be in [0, 20]");
  if (refine_neighbours < 1) Fail("attack: refine neighbours must be >= 1");
  if (min_shared < 0) Fail("attack: min shared must be >= 0");
  if (histogram_bins < 2 || histogram_bins > 100000)
    Fail("attack: histogram bins must be in [2, 100000]");
  if (trimmed_votes < 0) Fail("attack: trimmed votes must be >= 0");
  if (!(min_excess >= 0 && min_excess <= 1)) Fail("attack: min excess must be in [0, 1]");
  if (!(max_seconds >= 0 && std::isfinite(max_seconds))) {
    Fail("attack: --max-seconds must be a finite number >= 0 (0: no limit)");
  }
}

double VotePeak(std::vector<double>* votes, int bins, int trimmed, double min_excess,
                double* share) {
  std::vector<double>& v = *votes;
  const size_t total = v.size();
  if (share) *share = 0;
  if (total == 0) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  size_t lo = 0, hi = total;
  if (hi - lo > 2 * static_cast<size_t>(trimmed) + 5) lo += trimmed, hi -= trimmed;
  std::vector<double> d(bins + 1);
  std::vector<int> hist(bins);
  while (hi - lo > 5) {
    const double a = v[lo], b = v[hi - 1];
    if (!(b > a)) break;
    const double m = static_cast<double>(hi - lo);
    std::fill(hist.begin(), hist.end(), 0);
    for (size_t k = lo; k < hi; ++k) {
      const int bin = static_cast<int>((v[k] - a) / (b - a) * bins);
      ++hist[std::clamp(bin, 0, bins - 1)];
    }
    // d[k]: empirical minus uniform CDF at the k-th edge; the peak is the
    // interval of edges (s, e) with the largest d[e] − d[s].
    d[0] = 0;
    for (int k = 0; k < bins; ++k) d[k + 1] = d[k] + hist[k] / m - 1.0 / bins;
    double best = -1, min_d = d[0];
    int s = 0, e = bins, min_k = 0;
    for (int k = 1; k <= bins; ++k) {
      if (d[k] - min_d > best) best = d[k] - min_d, s = min_k, e = k;
      if (d[k] < min_d) min_d = d[k], min_k = k;
    }
    const double xs = a + (b - a) * s / bins, xe = a + (b - a) * e / bins;
    const size_t nlo = std::lower_bound(v.begin() + lo, v.begin() + hi, xs) - v.begin();
    const size_t nhi = std::upper_bound(v.begin() + lo, v.begin() + hi, xe) - v.begin();
    if (nhi <= nlo || (nlo == lo && nhi == hi)) break;
    lo = nlo, hi = nhi;
    if (best < min_excess) break;
  }
  if (share) *share = static_cast<double>(hi - lo) / total;
  const size_t mid = lo + (hi - lo) / 2;
  return (hi - lo) % 2 ? v[mid] : 0.5 * (v[mid - 1] + v[mid]);
}

DensityAttackResult RunDensityAttack(const LineCloud& cloud, const DensityAttackOptions& options) {
  options.Check();
  const auto start = std::chrono::steady_clock::now();
  const size_t n = cloud.size();
  if (n < kMinLines) {
    Fail("attack: the map has {} lines; the density attack needs at least {}", n, kMinLines);
  }
  if (n > std::numeric_limits<uint32_t>::max()) Fail("attack: more than 2^32 lines");
  const LineArrays a = MakeLineArrays(cloud.lines, MedianAnchor(cloud));
  const size_t k_lines =
      options.line_neighbours > 0
          ? std::min<size_t>(options.line_neighbours, n - 1)
          : std::min(n - 1, std::max<size_t>(std::min<size_t>(500, n / 20), kMinLines));
  const size_t k_refine = std::min<size_t>(options.refine_neighbours, n - 1);
  const int threads = WorkerThreads(options.threads);
  std::vector<Scratch> scratch(threads);
  for (Scratch& s : scratch) s.d2.resize(n);

  DensityAttackResult result;
  result.line_neighbours = static_cast<int>(k_lines);
  std::vector<double> t(n, 0.0), t_next(n, 0.0);
  std::vector<float> share(n, 0.f);
  auto peak = [&](Scratch& s, size_t i, std::vector<double>* out) {
    double sh = 0;
    const double p =
        VotePeak(&s.votes, options.histogram_bins, options.trimmed_votes, options.min_excess, &sh);
    (*out)[i] = std::isfinite(p) ? p : 0.0;
    share[i] = static_cast<float>(sh);
  };

  // The time budget: every row checks it (a row costs O(n), the check O(1)).
  const int passes = 1 + 2 * options.refine_rounds;
  std::atomic<size_t> rows_done{0};
  const auto check_budget = [&](const char* stage) {
    const size_t done = rows_done.fetch_add(1) + 1;
    if (options.max_seconds <= 0) return;
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (elapsed > options.max_seconds) {
      const double projected =
          elapsed * static_cast<double>(passes) * n / std::max<size_t>(done, 1);
      Fail(
          "attack: stopped at --max-seconds {:g} during {} ({} lines; the whole attack would take "
          "about {:.0f} s on {} threads)",
          options.max_seconds, stage, n, projected, threads);
    }
  };

  // Coarse: votes from the K nearest lines.
  ParallelFor(
      n, threads,
      [&](size_t i, int w) {
        check_budget("the coarse estimates");
        Scratch& s = scratch[w];
        LineToLinesSq(a, i, s.d2.data());
        s.d2[i] = kInf;  // a line is never its own neighbour
        SmallestK(s.d2, k_lines, &s.select, &s.a);
        Votes(a, i, s.a, &s.votes);
        peak(s, i, &t);
      },
      StageProgress(options, "coarse estimates (line-to-line neighbours)"));

  // Refinement: neighbourhoods from the current estimates.
  for (int round = 0; round < options.refine_rounds; ++round) {
    std::vector<Eigen::Vector3d> estimates(n);
    for (size_t i = 0; i < n; ++i) estimates[i] = a.q[i] + t[i] * a.v[i];
    const PointArrays p = MakePointArrays(estimates);
    ParallelFor(
        n, threads,
        [&](size_t i, int w) {
          check_budget("a refinement round");
          Scratch& s = scratch[w];
          LineToPointsSq(a, i, p, s.d2.data());
          s.d2[i] = kInf;
          SmallestK(s.d2, k_refine, &s.select, &s.a);
          PointToLinesSq(p, i, a, s.d2.data());
          s.d2[i] = kInf;
          SmallestK(s.d2, k_refine, &s.select, &s.b);
          std::sort(s.a.begin(), s.a.end());
          std::sort(s.b.begin(), s.b.end());
          s.shared.clear();
          std::set_intersection(s.a.begin(), s.a.end(), s.b.begin(), s.b.end(),
                                std::back_inserter(s.shared));
          Votes(a, i, s.shared.size() > static_cast<size_t>(options.min_shared) ? s.shared : s.a,
                &s.votes);
          peak(s, i, &t_next);
        },
        StageProgress(options, "refinement round " + std::to_string(round + 1)));
    t.swap(t_next);
  }

  result.points.resize(n);
  for (size_t i = 0; i < n; ++i) {
    result.points[i] = a.centre + a.q[i] + t[i] * a.v[i];
    if (share[i] == 0.f) ++result.lines_without_votes;
  }
  result.peak_share = std::move(share);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace linecloud
