#include "linecloud/privacy/density_attack.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>

#include "linecloud/privacy/line_neighbours.h"
#include "linecloud/util/error.h"
#include "linecloud/util/parallel.h"

namespace linecloud {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr size_t kMinLines = 10;

// Per-thread scratch.
struct Scratch {
  std::vector<float> d2;  // exact searches: one distance per line
  SelectBuffers select;
  NeighbourGrid::Buffers grid;
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

// The grid's entries (4 bytes each): 512 MB at most.
constexpr size_t kGridEntries = size_t{1} << 27;
// Rows sampled to size the grid's search radii, and the share of them that
// must find their k neighbours within the radius (before a 1.5 margin).
constexpr size_t kRadiusSamples = 512;
constexpr double kRadiusQuantile = 0.95, kRadiusMargin = 1.5;
// The box the grid covers: the sampled lines' coarse estimates between their
// 0.1 % and 99.9 % per axis, grown by 30 % of its diagonal. Crossings beyond
// it are not searched (on a seeded 182 000-line room they only add noise:
// 29.1 % of the points recovered within 1 % of the diagonal, 27.4 % with
// every pair, 27.0 % with a box grown by 100 %).
constexpr double kBoxQuantile = 0.001, kBoxMargin = 0.3;

// The three searches of the attack: exact (every pair) up to
// `exact_search_lines` lines, else through a NeighbourGrid.
class Search {
 public:
  Search(const LineArrays& a, size_t k_lines, const DensityAttackOptions& o)
      : a_(a), threads_(o.threads) {
    if (a.size() <= static_cast<size_t>(o.exact_search_lines)) return;
    // The attacker's box: where the sampled lines' coarse estimates fall.
    const size_t samples = std::min(a.size(), 4 * kRadiusSamples);
    std::vector<Eigen::Vector3d> sampled(samples, Eigen::Vector3d::Constant(kInf));
    std::vector<Scratch> scratch(WorkerThreads(o.threads));
    ParallelFor(samples, o.threads, [&](size_t m, int worker) {
      Scratch& s = scratch[worker];
      s.d2.resize(a.size());
      const size_t i = m * a.size() / samples;
      CoarseVotes(i, k_lines, &s);
      const double t = VotePeak(&s.votes, o.histogram_bins, o.trimmed_votes, o.min_excess);
      if (std::isfinite(t)) sampled[m] = a.q[i] + t * a.v[i];
    });
    std::vector<Eigen::Vector3d> estimates;
    for (const Eigen::Vector3d& x : sampled) {
      if (x.allFinite()) estimates.push_back(x);
    }
    r_lines_ = kRadiusMargin * SampledRadius(
                                   a.size(), k_lines, kRadiusQuantile, kRadiusSamples,
                                   [&](size_t i, float* d2) {
                                     LineToLinesSq(a, i, d2);
                                     d2[i] = kInf;
                                   },
                                   a.size(), o.threads);
    if (!(r_lines_ > 0)) return;  // no line has a neighbour: nothing a grid could find
    grid_.emplace(a, RobustBox(estimates, kBoxQuantile, kBoxMargin), r_lines_, kGridEntries);
  }
  bool exact() const { return !grid_; }
  double line_radius() const { return r_lines_; }

  // The coarse step's line searches, all lines at once on the grid.
  void PrepareCoarse(size_t k, int threads, const std::function<void()>& each_cell) {
    if (grid_) coarse_ = grid_->CoarseVotes(k, threads, each_cell);
  }
  size_t short_of_neighbours() const { return coarse_ ? coarse_->short_of_k : 0; }
  // The coarse votes of line i: from its k nearest lines.
  // Through the grid, unless the line's neighbourhood was too crowded to keep.
  void CoarseVotes(size_t i, size_t k, Scratch* s) const {
    if (coarse_ && !coarse_->exact[i]) {
      s->votes.assign(coarse_->t.begin() + coarse_->starts[i],
                      coarse_->t.begin() + coarse_->starts[i + 1]);
      return;
    }
    s->d2.resize(a_.size());
    LineToLinesSq(a_, i, s->d2.data());
    s->d2[i] = kInf;  // a line is never its own neighbour
    SmallestK(s->d2, k, &s->select, &s->a);
    Votes(a_, i, s->a, &s->votes);
  }

  // Before a refinement round: its estimates, and the radii that hold the
  // k nearest of most lines and points.
  void SetPoints(const PointArrays* p, size_t k) {
    p_ = p;
    if (!grid_) return;
    grid_->SetPoints(p);
    const auto radius = [&](const std::function<void(size_t, float*)>& d2s) {
      return kRadiusMargin *
             SampledRadius(a_.size(), k, kRadiusQuantile, kRadiusSamples, d2s, a_.size(), threads_);
    };
    r_line_point_ = radius([&](size_t i, float* d2) {
      LineToPointsSq(a_, i, *p, d2);
      d2[i] = kInf;
    });
    r_point_line_ = radius([&](size_t i, float* d2) {
      PointToLinesSq(*p, i, a_, d2);
      d2[i] = kInf;
    });
    // A radius of many cells reads more entries through the grid than every
    // line or point once (a small map's): then that search compares all.
    const LineGrid& g = grid_->grid();
    const double n = static_cast<double>(a_.size()), cells = static_cast<double>(g.num_cells());
    const auto across = [&](double r) { return 2 * r / g.cell() + 1; };
    const double lines_read = std::pow(across(r_point_line_), 3) * g.entries() / cells;
    const double points_read = g.dims().maxCoeff() * std::pow(across(r_line_point_), 2) * n / cells;
    exact_lines_near_point_ = lines_read > n / 4;
    exact_points_near_line_ = points_read > n / 4;
  }
  // The order to visit the lines in: by the cell of their estimate on the
  // grid (neighbouring queries read the same cells), else as they are.
  std::vector<uint32_t> QueryOrder() const {
    std::vector<uint32_t> order(a_.size());
    std::iota(order.begin(), order.end(), 0u);
    if (!grid_) return order;
    std::vector<int64_t> cell(a_.size());
    for (size_t i = 0; i < a_.size(); ++i) {
      cell[i] = grid_->grid().CellOf(Eigen::Vector3d(p_->x[i], p_->y[i], p_->z[i]));
    }
    std::stable_sort(order.begin(), order.end(),
                     [&](uint32_t x, uint32_t y) { return cell[x] < cell[y]; });
    return order;
  }
  void PointsNearLine(size_t i, size_t k, Scratch* s, std::vector<uint32_t>* out) const {
    if (grid_ && !exact_points_near_line_) {
      return grid_->NearestPoints(i, k, r_line_point_, &s->grid, out);
    }
    s->d2.resize(a_.size());
    LineToPointsSq(a_, i, *p_, s->d2.data());
    s->d2[i] = kInf;
    SmallestK(s->d2, k, &s->select, out);
  }
  void LinesNearPoint(size_t i, size_t k, Scratch* s, std::vector<uint32_t>* out) const {
    if (grid_ && !exact_lines_near_point_) {
      return grid_->NearestLinesToPoint(i, k, r_point_line_, &s->grid, out);
    }
    s->d2.resize(a_.size());
    PointToLinesSq(*p_, i, a_, s->d2.data());
    s->d2[i] = kInf;
    SmallestK(s->d2, k, &s->select, out);
  }

 private:
  const LineArrays& a_;
  int threads_;
  std::optional<NeighbourGrid> grid_;
  std::optional<NeighbourGrid::LineVotes> coarse_;
  const PointArrays* p_ = nullptr;
  double r_lines_ = 0, r_line_point_ = 0, r_point_line_ = 0;
  bool exact_points_near_line_ = false, exact_lines_near_point_ = false;
};

// The time budget: every row checks it (a row costs at most O(n), the check
// O(1)); past it, an Error with the projected time of the whole attack.
class BudgetCheck {
 public:
  // `uniform`: every row costs alike (the exact search), so the elapsed
  // time projects the whole attack's.
  BudgetCheck(const DensityAttackOptions& o, std::chrono::steady_clock::time_point start, size_t n,
              int threads, bool uniform)
      : o_(o), start_(start), n_(n), threads_(threads), uniform_(uniform) {}
  void operator()(const char* stage) const {
    rows_done_.fetch_add(1);
    Time(stage);
  }
  // The check alone (no row done).
  void Time(const char* stage) const {
    const size_t done = rows_done_.load();
    if (o_.max_seconds <= 0) return;
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    if (elapsed <= o_.max_seconds) return;
    if (!uniform_) {
      Fail("attack: stopped at --max-seconds {:g} during {} ({} lines, grid search, {} threads)",
           o_.max_seconds, stage, n_, threads_);
    }
    const double passes = 1 + 2 * o_.refine_rounds;
    const double projected = elapsed * passes * n_ / std::max<size_t>(done, 1);
    Fail(
        "attack: stopped at --max-seconds {:g} during {} ({} lines; the whole attack would take "
        "about {:.0f} s on {} threads)",
        o_.max_seconds, stage, n_, projected, threads_);
  }

 private:
  const DensityAttackOptions& o_;
  std::chrono::steady_clock::time_point start_;
  size_t n_;
  int threads_;
  bool uniform_;
  mutable std::atomic<size_t> rows_done_{0};
};

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
  if (exact_search_lines < 0) Fail("attack: exact search lines must be >= 0");
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
  Search search(a, k_lines, options);
  std::vector<Scratch> scratch(threads);
  if (search.exact()) {
    for (Scratch& s : scratch) s.d2.resize(n);
  }

  DensityAttackResult result;
  result.line_neighbours = static_cast<int>(k_lines);
  result.search_radius = search.line_radius();
  std::vector<double> t(n, 0.0), t_next(n, 0.0);
  std::vector<float> share(n, 0.f);
  auto peak = [&](Scratch& s, size_t i, std::vector<double>* out) {
    double sh = 0;
    const double p =
        VotePeak(&s.votes, options.histogram_bins, options.trimmed_votes, options.min_excess, &sh);
    (*out)[i] = std::isfinite(p) ? p : 0.0;
    share[i] = static_cast<float>(sh);
  };
  const BudgetCheck check_budget(options, start, n, threads, search.exact());

  // Coarse: votes from the K nearest lines.
  search.PrepareCoarse(k_lines, threads, [&] { check_budget.Time("the coarse estimates (grid)"); });
  ParallelFor(
      n, threads,
      [&](size_t i, int w) {
        check_budget("the coarse estimates");
        Scratch& s = scratch[w];
        search.CoarseVotes(i, k_lines, &s);
        peak(s, i, &t);
      },
      StageProgress(options, "coarse estimates (line-to-line neighbours)"));

  // Refinement: neighbourhoods from the current estimates.
  for (int round = 0; round < options.refine_rounds; ++round) {
    std::vector<Eigen::Vector3d> estimates(n);
    for (size_t i = 0; i < n; ++i) estimates[i] = a.q[i] + t[i] * a.v[i];
    const PointArrays p = MakePointArrays(estimates);
    search.SetPoints(&p, k_refine);
    const std::vector<uint32_t> order = search.QueryOrder();
    ParallelFor(
        n, threads,
        [&](size_t row, int w) {
          const size_t i = order[row];
          check_budget("a refinement round");
          Scratch& s = scratch[w];
          search.PointsNearLine(i, k_refine, &s, &s.a);
          search.LinesNearPoint(i, k_refine, &s, &s.b);
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
  result.lines_short_of_neighbours = search.short_of_neighbours();

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
