#include "linecloud/privacy/line_neighbours.h"

#include <algorithm>
#include <cmath>
#include <limits>

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

}  // namespace linecloud
