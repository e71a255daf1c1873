#include "linecloud/privacy/line_neighbours.h"

#include <algorithm>
#include <cmath>
#include <atomic>
#include <limits>

#include "linecloud/util/parallel.h"

namespace linecloud {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
// 1 − cos² below this: the lines are within ~0.6° of parallel.
constexpr float kMinSinSq = 1e-4f;

}  // namespace

LineArrays MakeLineArrays(std::span<const PluckerLine> lines, const Eigen::Vector3d& centre) {
  LineArrays a;
  a.centre = centre;
  const size_t n = lines.size();
  a.v.resize(n), a.q.resize(n);
  for (auto* f : {&a.vx, &a.vy, &a.vz, &a.qx, &a.qy, &a.qz, &a.wx, &a.wy, &a.wz}) f->resize(n);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d v = lines[i].v.normalized();
    // Anchor relative to the centre: the line's point closest to it.
    const Eigen::Vector3d p = lines[i].v.cross(lines[i].w) / lines[i].v.squaredNorm() - centre;
    const Eigen::Vector3d q = p - p.dot(v) * v;
    const Eigen::Vector3d w = q.cross(v);
    a.v[i] = v, a.q[i] = q;
    a.vx[i] = static_cast<float>(v.x()), a.vy[i] = static_cast<float>(v.y()),
    a.vz[i] = static_cast<float>(v.z());
    a.qx[i] = static_cast<float>(q.x()), a.qy[i] = static_cast<float>(q.y()),
    a.qz[i] = static_cast<float>(q.z());
    a.wx[i] = static_cast<float>(w.x()), a.wy[i] = static_cast<float>(w.y()),
    a.wz[i] = static_cast<float>(w.z());
  }
  return a;
}

PointArrays MakePointArrays(std::span<const Eigen::Vector3d> centred_points) {
  PointArrays p;
  p.x.resize(centred_points.size()), p.y.resize(centred_points.size()),
      p.z.resize(centred_points.size());
  for (size_t i = 0; i < centred_points.size(); ++i) {
    p.x[i] = static_cast<float>(centred_points[i].x());
    p.y[i] = static_cast<float>(centred_points[i].y());
    p.z[i] = static_cast<float>(centred_points[i].z());
  }
  return p;
}

void LineToLinesSq(const LineArrays& a, size_t i, float* d2) {
  LineToLinesSq(a, i, a, d2, kMinSinSq);
}

void LineToLinesSq(const LineArrays& from, size_t i, const LineArrays& to, float* __restrict d2,
                   float min_sin_sq) {
  const float vx = from.vx[i], vy = from.vy[i], vz = from.vz[i];
  const float wx = from.wx[i], wy = from.wy[i], wz = from.wz[i];
  const float* __restrict VX = to.vx.data();
  const float* __restrict VY = to.vy.data();
  const float* __restrict VZ = to.vz.data();
  const float* __restrict WX = to.wx.data();
  const float* __restrict WY = to.wy.data();
  const float* __restrict WZ = to.wz.data();
  const size_t n = to.size();
  for (size_t j = 0; j < n; ++j) {
    // Reciprocal product of the two Plücker lines: (q_j − q_i)·(v_i × v_j).
    const float num = vx * WX[j] + vy * WY[j] + vz * WZ[j] + VX[j] * wx + VY[j] * wy + VZ[j] * wz;
    const float c = vx * VX[j] + vy * VY[j] + vz * VZ[j];
    const float s2 = 1.f - c * c;
    // Near-parallel pairs divide by zero: +∞ (or NaN for 0/0), which no
    // selection keeps. Branch-free, so that the loop vectorises.
    d2[j] = num * num / (s2 > min_sin_sq ? s2 : 0.f);
  }
}

void LineToPointsSq(const LineArrays& a, size_t i, const PointArrays& p, float* __restrict d2) {
  const float vx = a.vx[i], vy = a.vy[i], vz = a.vz[i];
  const float qx = a.qx[i], qy = a.qy[i], qz = a.qz[i];
  const float* __restrict X = p.x.data();
  const float* __restrict Y = p.y.data();
  const float* __restrict Z = p.z.data();
  const size_t n = p.size();
  for (size_t j = 0; j < n; ++j) {
    const float rx = X[j] - qx, ry = Y[j] - qy, rz = Z[j] - qz;
    const float t = rx * vx + ry * vy + rz * vz;
    d2[j] = rx * rx + ry * ry + rz * rz - t * t;
  }
}

void PointToLinesSq(const PointArrays& p, size_t i, const LineArrays& a, float* __restrict d2) {
  const float x = p.x[i], y = p.y[i], z = p.z[i];
  const float* __restrict VX = a.vx.data();
  const float* __restrict VY = a.vy.data();
  const float* __restrict VZ = a.vz.data();
  const float* __restrict QX = a.qx.data();
  const float* __restrict QY = a.qy.data();
  const float* __restrict QZ = a.qz.data();
  const size_t n = a.size();
  for (size_t j = 0; j < n; ++j) {
    const float rx = x - QX[j], ry = y - QY[j], rz = z - QZ[j];
    const float t = rx * VX[j] + ry * VY[j] + rz * VZ[j];
    d2[j] = rx * rx + ry * ry + rz * rz - t * t;
  }
}

void SmallestK(std::span<const float> d2, size_t k, SelectBuffers* buffers,
               std::vector<uint32_t>* out) {
  out->clear();
  const size_t n = d2.size();
  if (k == 0 || n == 0) return;
  std::vector<uint32_t>& cand = buffers->candidates;
  cand.resize(n);
  float tau = kInf;
  constexpr size_t kSample = 512;
  if (n >= 2 * kSample && 4 * k < n) {
    // The threshold below which ~2k of the n values lie, from a strided sample.
    std::vector<float>& s = buffers->sample;
    s.resize(kSample);
    const size_t stride = n / kSample;
    for (size_t m = 0; m < kSample; ++m) {
      const float x = d2[m * stride];
      s[m] = std::isnan(x) ? kInf : x;  // NaN would break the ordering
    }
    const size_t rank = std::min(kSample - 1, (2 * k * kSample + n - 1) / n + 8);
    std::nth_element(s.begin(), s.begin() + rank, s.end());
    tau = s[rank];
  }
  size_t c = 0;
  for (int attempt = 0; attempt < 2; ++attempt) {
    c = 0;
    // Blocks of 16 whose minimum exceeds tau are skipped with one
    // (vectorised) test; the rest are gathered branch-free.
    constexpr size_t kBlock = 16;
    size_t j = 0;
    for (; j + kBlock <= n; j += kBlock) {
      float m = d2[j];
      for (size_t b = 1; b < kBlock; ++b) m = std::min(m, d2[j + b]);
      if (!(m <= tau) && !std::isnan(m)) continue;
      for (size_t b = j; b < j + kBlock; ++b) {
        cand[c] = static_cast<uint32_t>(b);
        c += d2[b] <= tau;  // false for NaN and for ∞ when tau is finite
      }
    }
    for (; j < n; ++j) {
      cand[c] = static_cast<uint32_t>(j);
      c += d2[j] <= tau;
    }
    if (c >= k || tau == kInf) break;
    tau = kInf;  // the sample was unlucky: take every finite value
  }
  if (tau == kInf) {
    // Keep finite values only.
    size_t f = 0;
    for (size_t m = 0; m < c; ++m) {
      if (std::isfinite(d2[cand[m]])) cand[f++] = cand[m];
    }
    c = f;
  }
  const size_t keep = std::min(k, c);
  auto by_distance = [&](uint32_t a, uint32_t b) { return d2[a] < d2[b]; };
  if (keep < c) std::nth_element(cand.begin(), cand.begin() + keep, cand.begin() + c, by_distance);
  out->assign(cand.begin(), cand.begin() + keep);
}

std::vector<PluckerLine> NeighbourGrid::Lines(const LineArrays& a) {
  std::vector<PluckerLine> lines(a.size());
  for (size_t i = 0; i < a.size(); ++i) lines[i] = PluckerLine(a.v[i], a.q[i].cross(a.v[i]));
  return lines;
}

NeighbourGrid::NeighbourGrid(const LineArrays& lines, const Eigen::AlignedBox3d& centred_box,
                             double pair_radius, size_t max_entries)
    : a_(lines),
      pair_radius_(pair_radius),
      grid_(Lines(lines), centred_box, 0.5 * pair_radius, max_entries) {
  rows_.resize(lines.size());
  for (size_t i = 0; i < lines.size(); ++i) {
    rows_[i] = {
        {lines.vx[i], lines.vy[i], lines.vz[i]}, {lines.qx[i], lines.qy[i], lines.qz[i]}, {}};
  }
}

void NeighbourGrid::Pick(size_t k, Buffers* b, std::vector<uint32_t>* out) const {
  SmallestK(b->d2, k, &b->select, &b->picked);
  out->clear();
  for (const uint32_t m : b->picked) out->push_back(b->ids[m]);
}

void NeighbourGrid::PairsOfCell(int64_t cell, int bins, CellScratch* scratch,
                                const std::function<void(const CellScratch&)>& flush) const {
  const std::span<const uint32_t> ids = grid_.LinesIn(cell);
  const size_t o = ids.size();
  std::vector<PairEnd>& ends = scratch->ends;
  ends.clear();
  if (o < 2) return;
  // The events so far, by line (counting sort): each line's row of the
  // totals is then touched once per batch.
  const auto hand_over = [&] {
    std::vector<uint32_t>& starts = scratch->starts;
    starts.assign(o + 1, 0);
    for (const PairEnd& e : ends) ++starts[e.line + 1];
    for (size_t m = 0; m < o; ++m) starts[m + 1] += starts[m];
    scratch->sorted.resize(ends.size());
    std::vector<uint32_t> fill(starts.begin(), starts.end() - 1);
    for (const PairEnd& e : ends) scratch->sorted[fill[e.line]++] = e;
    flush(*scratch);
    ends.clear();
  };
  constexpr size_t kBatch = size_t{1} << 20;
  // The cell's lines side by side (v, q, w; float), a row of distances, then
  // the pairs within the radius.
  std::vector<float>& local = scratch->rows;
  local.resize(10 * o);
  float* v[3] = {local.data(), local.data() + o, local.data() + 2 * o};
  float* q[3] = {local.data() + 3 * o, local.data() + 4 * o, local.data() + 5 * o};
  float* w[3] = {local.data() + 6 * o, local.data() + 7 * o, local.data() + 8 * o};
  float* __restrict d2 = local.data() + 9 * o;
  for (size_t m = 0; m < o; ++m) {
    const uint32_t i = ids[m];
    v[0][m] = a_.vx[i], v[1][m] = a_.vy[i], v[2][m] = a_.vz[i];
    q[0][m] = a_.qx[i], q[1][m] = a_.qy[i], q[2][m] = a_.qz[i];
    w[0][m] = a_.wx[i], w[1][m] = a_.wy[i], w[2][m] = a_.wz[i];
  }
  // The cell's own coordinates: a pair belongs to the cell holding its
  // midpoint (computed alike in every cell, so exactly one cell reports it).
  const Eigen::Array3i dims = grid_.dims();
  const Eigen::Array3d corner = grid_.corner().array();
  const double inv_cell = 1.0 / grid_.cell();
  const Eigen::Vector3d box_hi = grid_.box().max();
  const double cx = static_cast<double>(cell % dims[0]);
  const double cy = static_cast<double>((cell / dims[0]) % dims[1]);
  const double cz = static_cast<double>(cell / (static_cast<int64_t>(dims[0]) * dims[1]));
  const float r2 = static_cast<float>(pair_radius_ * pair_radius_);
  const double to_bin = bins / pair_radius_;
  const float* __restrict VX = v[0];
  const float* __restrict VY = v[1];
  const float* __restrict VZ = v[2];
  const float* __restrict WX = w[0];
  const float* __restrict WY = w[1];
  const float* __restrict WZ = w[2];
  for (size_t m = 0; m + 1 < o; ++m) {
    const float vx = VX[m], vy = VY[m], vz = VZ[m], wx = WX[m], wy = WY[m], wz = WZ[m];
    // Branch-free, so that it vectorises; near-parallel pairs get ∞ (or NaN).
    for (size_t n = m + 1; n < o; ++n) {
      const float c = vx * VX[n] + vy * VY[n] + vz * VZ[n];
      const float s2 = 1.f - c * c;
      const float num = vx * WX[n] + vy * WY[n] + vz * WZ[n] + VX[n] * wx + VY[n] * wy + VZ[n] * wz;
      d2[n] = num * num / (s2 > kMinSinSq ? s2 : 0.f);
    }
    for (size_t n = m + 1; n < o; ++n) {
      if (!(d2[n] <= r2)) continue;
      const float c = vx * VX[n] + vy * VY[n] + vz * VZ[n], s2 = 1.f - c * c;
      // Closest points q_m + t_m v_m and q_n + t_n v_n.
      const float rx = q[0][n] - q[0][m], ry = q[1][n] - q[1][m], rz = q[2][n] - q[2][m];
      const float rm = rx * vx + ry * vy + rz * vz;
      const float rn = rx * VX[n] + ry * VY[n] + rz * VZ[n];
      const float tm = (rm - c * rn) / s2, tn = (c * rm - rn) / s2;
      const double mx = 0.5 * (q[0][m] + tm * vx + q[0][n] + tn * VX[n]);
      const double my = 0.5 * (q[1][m] + tm * vy + q[1][n] + tn * VY[n]);
      const double mz = 0.5 * (q[2][m] + tm * vz + q[2][n] + tn * VZ[n]);
      // floor(x) == c for an integer c, without floor's cost.
      const double fx = (mx - corner[0]) * inv_cell, fy = (my - corner[1]) * inv_cell,
                   fz = (mz - corner[2]) * inv_cell;
      if (!(fx >= cx && fx < cx + 1 && fy >= cy && fy < cy + 1 && fz >= cz && fz < cz + 1)) {
        continue;
      }
      // The last cell of an axis reaches past the box: meetings there are outside it.
      if (!(mx <= box_hi[0] && my <= box_hi[1] && mz <= box_hi[2])) continue;
      const uint32_t bin =
          std::min<uint32_t>(bins - 1, static_cast<uint32_t>(std::sqrt(d2[n]) * to_bin));
      ends.push_back({static_cast<uint32_t>(m), bin, tm});
      ends.push_back({static_cast<uint32_t>(n), bin, tn});
    }
    if (ends.size() >= kBatch) hand_over();
  }
  if (!ends.empty()) hand_over();
}

NeighbourGrid::LineVotes NeighbourGrid::CoarseVotes(size_t k, int threads,
                                                    const std::function<void()>& each_cell) const {
  // Pass 1: each line's distances binned (32 bins up to the radius), and the
  // bin holding its k-th. Pass 2: the votes of the pairs in or below that bin.
  constexpr int kBins = 32;
  const uint64_t max_votes = 4 * static_cast<uint64_t>(k) + 64;
  const size_t n = a_.size();
  const size_t cells = static_cast<size_t>(grid_.num_cells());
  std::vector<uint32_t> hist(n * kBins, 0);
  std::vector<CellScratch> scratch(WorkerThreads(threads));
  ParallelFor(cells, threads, [&](size_t c, int worker) {
    if (each_cell) each_cell();
    const std::span<const uint32_t> ids = grid_.LinesIn(static_cast<int64_t>(c));
    PairsOfCell(static_cast<int64_t>(c), kBins, &scratch[worker], [&](const CellScratch& s) {
      for (size_t m = 0; m + 1 < s.starts.size(); ++m) {
        uint32_t* row = hist.data() + size_t{ids[m]} * kBins;
        for (uint32_t e = s.starts[m]; e < s.starts[m + 1]; ++e) {
          std::atomic_ref<uint32_t>(row[s.sorted[e].bin]).fetch_add(1, std::memory_order_relaxed);
        }
      }
    });
  });
  LineVotes votes;
  votes.starts.assign(n + 1, 0);
  votes.exact.assign(n, 0);
  std::vector<uint8_t> last_bin(n);
  for (size_t i = 0; i < n; ++i) {
    uint64_t total = 0;
    int b = 0;
    for (; b < kBins; ++b) {
      total += hist[i * kBins + b];
      if (total >= k) break;
    }
    if (b == kBins) ++votes.short_of_k, b = kBins - 1;
    last_bin[i] = static_cast<uint8_t>(b);
    if (total > max_votes) votes.exact[i] = 1, total = 0;
    votes.starts[i + 1] = votes.starts[i] + total;
  }
  std::vector<uint32_t>().swap(hist);
  votes.t.resize(votes.starts[n]);
  std::vector<uint64_t> fill(votes.starts.begin(), votes.starts.end() - 1);
  ParallelFor(cells, threads, [&](size_t c, int worker) {
    if (each_cell) each_cell();
    const std::span<const uint32_t> ids = grid_.LinesIn(static_cast<int64_t>(c));
    PairsOfCell(static_cast<int64_t>(c), kBins, &scratch[worker], [&](const CellScratch& s) {
      for (size_t m = 0; m + 1 < s.starts.size(); ++m) {
        const uint32_t i = ids[m];
        if (votes.exact[i]) continue;
        uint64_t kept = 0;
        for (uint32_t e = s.starts[m]; e < s.starts[m + 1]; ++e) {
          kept += s.sorted[e].bin <= last_bin[i];
        }
        if (kept == 0) continue;
        uint64_t at = std::atomic_ref<uint64_t>(fill[i]).fetch_add(kept, std::memory_order_relaxed);
        for (uint32_t e = s.starts[m]; e < s.starts[m + 1]; ++e) {
          if (s.sorted[e].bin <= last_bin[i]) votes.t[at++] = s.sorted[e].t;
        }
      }
    });
  });
  return votes;
}

void NeighbourGrid::SetPoints(const PointArrays* points) {
  points_ = points;
  const int64_t cells = grid_.num_cells();
  point_starts_.assign(cells + 1, 0);
  std::vector<int64_t> cell_of(points->size());
  for (size_t i = 0; i < points->size(); ++i) {
    cell_of[i] = grid_.CellOf(Eigen::Vector3d(points->x[i], points->y[i], points->z[i]));
    if (cell_of[i] >= 0) ++point_starts_[cell_of[i] + 1];
  }
  for (int64_t c = 0; c < cells; ++c) point_starts_[c + 1] += point_starts_[c];
  points_by_cell_.resize(point_starts_[cells]);
  std::vector<uint32_t> fill(point_starts_.begin(), point_starts_.end() - 1);
  for (size_t i = 0; i < points->size(); ++i) {
    if (cell_of[i] < 0) continue;
    points_by_cell_[fill[cell_of[i]]++] = {{points->x[i], points->y[i], points->z[i]},
                                           static_cast<uint32_t>(i)};
  }
}

void NeighbourGrid::NearestPoints(size_t i, size_t k, double r, Buffers* b,
                                  std::vector<uint32_t>* out) const {
  b->ids.clear(), b->d2.clear();
  const LineRow& l = rows_[i];
  grid_.CellsNear(PluckerLine(a_.v[i], a_.q[i].cross(a_.v[i])), r, &b->cells);
  const float r2 = static_cast<float>(r * r);
  for (const int64_t c : b->cells) {
    for (uint32_t m = point_starts_[c]; m < point_starts_[c + 1]; ++m) {
      const PointRow& p = points_by_cell_[m];
      const float rx = p.x[0] - l.q[0], ry = p.x[1] - l.q[1], rz = p.x[2] - l.q[2];
      const float t = rx * l.v[0] + ry * l.v[1] + rz * l.v[2];
      const float d2 = rx * rx + ry * ry + rz * rz - t * t;
      if (d2 > r2 || p.id == i) continue;  // (the line's own estimate left out)
      b->ids.push_back(p.id);
      b->d2.push_back(d2);
    }
  }
  Pick(k, b, out);
}

void NeighbourGrid::NearestLinesToPoint(size_t i, size_t k, double r, Buffers* b,
                                        std::vector<uint32_t>* out) const {
  b->ids.clear(), b->d2.clear();
  const float x = points_->x[i], y = points_->y[i], z = points_->z[i];
  grid_.CellsNear(Eigen::Vector3d(x, y, z), r, &b->cells);
  if (b->stamp.size() != a_.size()) b->stamp.assign(a_.size(), 0), b->epoch = 0;
  if (++b->epoch == 0) std::fill(b->stamp.begin(), b->stamp.end(), 0), b->epoch = 1;
  const float r2 = static_cast<float>(r * r);
  for (const int64_t c : b->cells) {
    for (const uint32_t j : grid_.LinesIn(c)) {
      const LineRow& l = rows_[j];
      const float rx = x - l.q[0], ry = y - l.q[1], rz = z - l.q[2];
      const float t = rx * l.v[0] + ry * l.v[1] + rz * l.v[2];
      const float d2 = rx * rx + ry * ry + rz * rz - t * t;
      // Within r (tested first: most candidates are not), not met in another
      // cell, not the point's own line.
      if (d2 > r2 || b->stamp[j] == b->epoch || j == i) continue;
      b->stamp[j] = b->epoch;
      b->ids.push_back(j);
      b->d2.push_back(d2);
    }
  }
  Pick(k, b, out);
}

double SampledRadius(size_t rows, size_t k, double quantile, size_t samples,
                     const std::function<void(size_t, float*)>& d2s, size_t other_size,
                     int threads) {
  samples = std::min(samples, rows);
  std::vector<double> kth(samples, -1);
  struct Local {
    std::vector<float> d2;
    SelectBuffers select;
    std::vector<uint32_t> nearest;
  };
  std::vector<Local> locals(WorkerThreads(threads));
  ParallelFor(samples, threads, [&](size_t m, int worker) {
    Local& l = locals[worker];
    l.d2.resize(other_size);
    d2s(m * rows / samples, l.d2.data());
    SmallestK(l.d2, k, &l.select, &l.nearest);  // finite values only
    float largest = -1;
    for (const uint32_t j : l.nearest) largest = std::max(largest, l.d2[j]);
    if (!l.nearest.empty()) kth[m] = std::sqrt(std::max(0.f, largest));
  });
  std::erase(kth, -1.0);
  if (kth.empty()) return 0;
  const size_t q = std::min(kth.size() - 1, static_cast<size_t>(quantile * kth.size()));
  std::nth_element(kth.begin(), kth.begin() + q, kth.end());
  return kth[q];
}

}  // namespace linecloud
