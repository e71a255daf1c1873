#include "linecloud/features/sift_scale_space.h"

extern "C" {
#include <vl/mathop.h>
#include <vl/sift.h>
}

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "linecloud/util/error.h"
#include "linecloud/util/multiversion.h"
#include "linecloud/util/parallel.h"

namespace linecloud {
namespace {

// VLFeat's VL_SHIFT_LEFT: x * 2^n for either sign of n.
int ShiftLeft(int x, int n) { return n >= 0 ? x << n : x >> -n; }

// Eight floats, loaded and stored unaligned (GCC / Clang vector extension;
// the compiler picks the widest instructions of each clone).
typedef float Floats8 __attribute__((vector_size(32), aligned(4)));
constexpr int kBlock = 32;  // four vectors of columns per pass over the taps

// acc[x] = sum_i rows[i][x] * filter[i], i ascending from 0, each product and
// sum rounded: VLFeat's column filter on one output row, all columns at once
// (rows[i] = the input's row y - W + i), or its row filter (rows[i] = the
// padded row shifted by i).
LINECLOUD_TARGET_CLONES void FilterColumns(const float* const* rows, const float* filter, int taps,
                                           int n, float* acc) {
  int x = 0;
  for (; x + kBlock <= n; x += kBlock) {
    Floats8 a0 = {}, a1 = {}, a2 = {}, a3 = {};
    for (int i = 0; i < taps; ++i) {
      const Floats8* r = reinterpret_cast<const Floats8*>(rows[i] + x);
      const float c = filter[i];
      a0 += r[0] * c;
      a1 += r[1] * c;
      a2 += r[2] * c;
      a3 += r[3] * c;
    }
    Floats8* out = reinterpret_cast<Floats8*>(acc + x);
    out[0] = a0;
    out[1] = a1;
    out[2] = a2;
    out[3] = a3;
  }
  for (; x < n; ++x) {
    float a = 0.0f;
    for (int i = 0; i < taps; ++i) a += rows[i][x] * filter[i];
    acc[x] = a;
  }
}

// `in` (width x height) doubled by VLFeat's linear interpolation: samples kept
// at even positions, the mean of two neighbours at odd ones, the last sample
// repeated (copy_and_upsample_rows, once per axis).
void Upsample(const float* in, int width, int height, float* out) {
  const int w2 = 2 * width;
  std::vector<float> rows(static_cast<size_t>(w2) * height);  // doubled along x
  for (int y = 0; y < height; ++y) {
    const float* src = in + static_cast<size_t>(y) * width;
    float* dst = rows.data() + static_cast<size_t>(y) * w2;
    for (int x = 0; x + 1 < width; ++x) {
      dst[2 * x] = src[x];
      dst[2 * x + 1] = static_cast<float>(0.5 * (src[x] + src[x + 1]));
    }
    dst[w2 - 2] = dst[w2 - 1] = src[width - 1];
  }
  for (int y = 0; y + 1 < height; ++y) {
    const float* a = rows.data() + static_cast<size_t>(y) * w2;
    const float* b = a + w2;
    float* even = out + static_cast<size_t>(2 * y) * w2;
    float* odd = even + w2;
    for (int x = 0; x < w2; ++x) {
      even[x] = a[x];
      odd[x] = static_cast<float>(0.5 * (a[x] + b[x]));
    }
  }
  const float* last = rows.data() + static_cast<size_t>(height - 1) * w2;
  std::memcpy(out + static_cast<size_t>(2 * height - 2) * w2, last, sizeof(float) * w2);
  std::memcpy(out + static_cast<size_t>(2 * height - 1) * w2, last, sizeof(float) * w2);
}

// Every (2^d)-th sample of every (2^d)-th row: out is (width >> d) x (height >> d).
void Downsample(const float* in, int width, int height, int d, float* out) {
  const int step = 1 << d, w = width >> d, h = height >> d;
  for (int y = 0; y < h; ++y) {
    const float* src = in + static_cast<size_t>(y) * step * width;
    for (int x = 0; x < w; ++x) *out++ = src[static_cast<size_t>(x) * step];
  }
}

// `in` smoothed by sigma into `out`, or copied when sigma is not positive.
void SmoothOrCopy(const float* in, float* out, int width, int height, double sigma, int threads) {
  if (sigma > 0) {
    SmoothGaussian(in, out, width, height, VlFeatGaussianFilter(sigma), threads);
  } else {
    std::memcpy(out, in, sizeof(float) * width * height);
  }
}

// Every level after the first: each the previous smoothed by VLFeat's step.
void FillLevels(VlSiftFilt* f, int threads) {
  const int w = f->octave_width, h = f->octave_height;
  for (int s = f->s_min + 1; s <= f->s_max; ++s) {
    const double sd = f->dsigma0 * std::pow(f->sigmak, s);
    SmoothGaussian(vl_sift_get_octave(f, s - 1), vl_sift_get_octave(f, s), w, h,
                   VlFeatGaussianFilter(sd), threads);
  }
}

// The smallest float f with (double) f >= 1e-8: x < f is VLFeat's test
// x < 1e-8 (a float against a double) in float arithmetic.
float FastSqrtZeroBelow() {
  float f = static_cast<float>(1e-8);
  if (static_cast<double>(f) < 1e-8) f = std::nextafter(f, 1.0f);
  return f;
}

typedef int32_t Ints8 __attribute__((vector_size(32), aligned(4)));
typedef double Doubles8 __attribute__((vector_size(64), aligned(8)));

// Modulus and angle in [0, 2 pi) of n gradients, interleaved into `out`:
// vl_fast_sqrt_f(gx^2 + gy^2) and vl_mod_2pi_f(vl_fast_atan2_f(gy, gx) + 2 pi),
// eight at a time with the same operations (the arc tangent lies within
// (-pi, pi), so the modulo is one subtraction of 2 pi at most).
LINECLOUD_TARGET_CLONES void GradientPolar(const float* gx, const float* gy, int n,
                                           float zero_below, float* out) {
  const float two_pi = static_cast<float>(2 * VL_PI);
  int i = 0;
  for (; i + 8 <= n; i += 8) {
    const Floats8 x = *reinterpret_cast<const Floats8*>(gx + i);
    const Floats8 y = *reinterpret_cast<const Floats8*>(gy + i);
    // vl_fast_sqrt_f: m2 times the bit-trick inverse square root, two Newton steps.
    const Floats8 m2 = x * x + y * y;
    const Floats8 half = 0.5f * m2;
    Floats8 r = (Floats8)(0x5f3759df - ((Ints8)m2 >> 1));
    r = r * (1.5f - half * r * r);
    r = r * (1.5f - half * r * r);
    const Floats8 zero = {};
    const Floats8 mod = m2 < zero_below ? zero : m2 * r;
    // vl_fast_atan2_f.
    const Floats8 abs_y = (Floats8)((Ints8)y & 0x7fffffff) + VL_EPSILON_F;
    const auto right = x >= 0;
    const Floats8 t = (right ? x - abs_y : x + abs_y) / (right ? x + abs_y : abs_y - x);
    Floats8 angle =
        right ? static_cast<float>(VL_PI / 4) + zero : static_cast<float>(3 * VL_PI / 4) + zero;
    angle += (0.1821f * t * t - 0.9675f) * t;
    const Floats8 atan = y < 0 ? -angle : angle;
    const Doubles8 wide = __builtin_convertvector(atan, Doubles8) + 2 * VL_PI;
    Floats8 a = __builtin_convertvector(wide, Floats8);
    a = a > two_pi ? a - two_pi : a;
    for (int j = 0; j < 8; ++j) {
      out[2 * (i + j)] = mod[j];
      out[2 * (i + j) + 1] = a[j];
    }
  }
  for (; i < n; ++i) {
    out[2 * i] = vl_fast_sqrt_f(gx[i] * gx[i] + gy[i] * gy[i]);
    out[2 * i + 1] = vl_mod_2pi_f(vl_fast_atan2_f(gy[i], gx[i]) + 2 * VL_PI);
  }
}

// One row of a level's gradient: central differences inside, one-sided ones
// on the border (VLFeat's update_gradient), then modulus and angle.
void GradientRow(const float* level, int w, int h, int y, float* gx, float* gy, float* out) {
  const float* row = level + static_cast<size_t>(y) * w;
  const float* up = y > 0 ? row - w : row;
  const float* down = y + 1 < h ? row + w : row;
  const bool inner_row = y > 0 && y + 1 < h;
  for (int x = 0; x < w; ++x) {
    const float dy = down[x] - up[x];
    gy[x] = inner_row ? static_cast<float>(0.5 * dy) : dy;
  }
  gx[0] = row[1] - row[0];
  for (int x = 1; x + 1 < w; ++x) gx[x] = static_cast<float>(0.5 * (row[x + 1] - row[x - 1]));
  gx[w - 1] = row[w - 1] - row[w - 2];
  static const float zero_below = FastSqrtZeroBelow();
  GradientPolar(gx, gy, w, zero_below, out);
}

// VLFeat's fast_expn: exp(-x) for x in [0, 25] by linear interpolation in a
// table of 257 samples, 0 beyond.
struct ExpTable {
  double samples[257];
  ExpTable() {
    for (int k = 0; k <= 256; ++k) samples[k] = std::exp(-static_cast<double>(k) * (25.0 / 256));
  }
  double operator()(double x) const {
    if (x > 25.0) return 0.0;
    x *= 256 / 25.0;
    const int i = static_cast<int>(vl_floor_d(x));
    const double r = x - i;
    return samples[i] + r * (samples[i + 1] - samples[i]);
  }
};
const ExpTable& FastExpn() {
  static const ExpTable table;
  return table;
}

// VLFeat's normalize_histogram: divided by its (fast) L2 norm.
void NormalizeHistogram(float* h, int n) {
  float norm = 0.0f;
  for (int i = 0; i < n; ++i) norm += h[i] * h[i];
  norm = vl_fast_sqrt_f(norm) + VL_EPSILON_F;
  for (int i = 0; i < n; ++i) h[i] /= norm;
}

// Normalised, truncated at 0.2, normalised again (VLFeat's norm threshold is 0).
void NormalizeDescriptor(float* d) {
  constexpr int n = 128;
  NormalizeHistogram(d, n);
  for (int i = 0; i < n; ++i) {
    if (d[i] > 0.2) d[i] = 0.2f;
  }
  NormalizeHistogram(d, n);
}

// One row of samples, dx = x0 + i: VLFeat's rotated and scaled offsets
// (double arithmetic rounded to float as VLFeat's) and the window's argument.
LINECLOUD_TARGET_CLONES void RotateRow(double x0, int n, double ct0, double st0, double sdy,
                                       double cdy, double spatial_bin, double window_scale,
                                       float* __restrict nx, float* __restrict ny,
                                       double* __restrict r2) {
  for (int i = 0; i < n; ++i) {
    const float dx = static_cast<float>(x0 + i);
    const float a = static_cast<float>((ct0 * dx + sdy) / spatial_bin);
    const float b = static_cast<float>((-st0 * dx + cdy) / spatial_bin);
    nx[i] = a;
    ny[i] = b;
    r2[i] = (a * a + b * b) / window_scale;
  }
}

// Per-thread rows of DescribeKeypoint.
struct RowScratch {
  std::vector<float> nx, ny;
  std::vector<double> r2;
};
RowScratch& Scratch() {
  thread_local RowScratch scratch;
  return scratch;
}

}  // namespace

std::vector<float> VlFeatGaussianFilter(double sigma) {
  const int width = static_cast<int>(std::max(std::ceil(4.0 * sigma), 1.0));
  std::vector<float> filter(2 * width + 1);
  float sum = 0;
  for (int j = 0; j < 2 * width + 1; ++j) {
    const float d = static_cast<float>(j - width) / static_cast<float>(sigma);
    filter[j] = static_cast<float>(std::exp(-0.5 * (d * d)));
    sum += filter[j];
  }
  for (float& c : filter) c /= sum;
  return filter;
}

void SmoothGaussian(const float* in, float* out, int width, int height,
                    const std::vector<float>& filter, int threads) {
  const int taps = static_cast<int>(filter.size());
  const int half = taps / 2;
  struct Buffers {
    std::vector<const float*> rows, shifted;
    std::vector<float> padded;
  };
  std::vector<Buffers> buffers(WorkerThreads(threads));
  ParallelFor(height, threads, [&](size_t y, int worker) {
    Buffers& b = buffers[worker];
    b.rows.resize(taps);
    b.shifted.resize(taps);
    b.padded.resize(static_cast<size_t>(width) + 2 * half);
    for (int i = 0; i < taps; ++i) {
      const int source = std::clamp(static_cast<int>(y) - half + i, 0, height - 1);
      b.rows[i] = in + static_cast<size_t>(source) * width;
    }
    float* columns = b.padded.data() + half;
    FilterColumns(b.rows.data(), filter.data(), taps, width, columns);
    std::fill(b.padded.begin(), b.padded.begin() + half, columns[0]);
    std::fill(b.padded.end() - half, b.padded.end(), columns[width - 1]);
    for (int i = 0; i < taps; ++i) b.shifted[i] = b.padded.data() + i;
    FilterColumns(b.shifted.data(), filter.data(), taps, width, out + y * width);
  });
}

bool ProcessFirstOctave(VlSiftFilt* f, const float* image, int threads) {
  if (f->o_min < -1) Fail("the first SIFT octave must be -1 or above here, got {}", f->o_min);
  f->o_cur = f->o_min;
  f->nkeys = 0;
  const int w = f->octave_width = ShiftLeft(f->width, -f->o_cur);
  const int h = f->octave_height = ShiftLeft(f->height, -f->o_cur);
  if (f->O == 0) return false;

  // The octave's base image, before smoothing, in f->temp (w x h floats).
  if (f->o_min == -1) {
    Upsample(image, f->width, f->height, f->temp);
  } else if (f->o_min > 0) {
    Downsample(image, f->width, f->height, f->o_min, f->temp);
  } else {
    std::memcpy(f->temp, image, sizeof(float) * w * h);
  }
  // The input's nominal smoothing (sigman) brought to the first level's.
  const double sa = f->sigma0 * std::pow(f->sigmak, f->s_min);
  const double sb = f->sigman * std::pow(2.0, -f->o_min);
  SmoothOrCopy(f->temp, vl_sift_get_octave(f, f->s_min), w, h,
               sa > sb ? std::sqrt(sa * sa - sb * sb) : 0.0, threads);
  FillLevels(f, threads);
  return true;
}

bool ProcessNextOctave(VlSiftFilt* f, int threads) {
  if (f->o_cur == f->o_min + f->O - 1) return false;
  const int s_best = std::min(f->s_min + f->S, f->s_max);
  Downsample(vl_sift_get_octave(f, s_best), f->octave_width, f->octave_height, 1, f->temp);
  f->o_cur += 1;
  f->nkeys = 0;
  const int w = f->octave_width = ShiftLeft(f->width, -f->o_cur);
  const int h = f->octave_height = ShiftLeft(f->height, -f->o_cur);
  // VLFeat computes these two in single precision (powf).
  const float k = static_cast<float>(f->sigmak);
  const double sa = f->sigma0 * std::pow(k, static_cast<float>(f->s_min));
  const double sb = f->sigma0 * std::pow(k, static_cast<float>(s_best - f->S));
  SmoothOrCopy(f->temp, vl_sift_get_octave(f, f->s_min), w, h,
               sa > sb ? std::sqrt(sa * sa - sb * sb) : 0.0, threads);
  FillLevels(f, threads);
  return true;
}

void UpdateGradients(VlSiftFilt* f, int threads) {
  if (f->grad_o == f->o_cur) return;
  const int w = f->octave_width, h = f->octave_height;
  const int levels = f->s_max - 2 - f->s_min;  // s_min + 1 .. s_max - 2
  std::vector<std::vector<float>> differences(WorkerThreads(threads));
  ParallelFor(static_cast<size_t>(levels) * h, threads, [&](size_t i, int worker) {
    const int level = static_cast<int>(i / h), y = static_cast<int>(i % h);
    const float* image = vl_sift_get_octave(f, f->s_min + 1 + level);
    float* grad = f->grad + 2 * (static_cast<size_t>(level) * w * h + static_cast<size_t>(y) * w);
    std::vector<float>& d = differences[worker];
    d.resize(2 * static_cast<size_t>(w));
    GradientRow(image, w, h, y, d.data(), d.data() + w, grad);
  });
  f->grad_o = f->o_cur;
}

void DescribeKeypoint(const VlSiftFilt* f, const VlSiftKeypoint& k, double angle0,
                      float* descriptor) {
  constexpr int kBins = 4, kAngles = 8;  // VLFeat's NBP and NBO
  const int w = f->octave_width, h = f->octave_height;
  const double xper = std::pow(2.0, f->o_cur);
  const double x = k.x / xper, y = k.y / xper, sigma = k.sigma / xper;
  const int xi = static_cast<int>(x + 0.5), yi = static_cast<int>(y + 0.5), si = k.is;
  const double st0 = std::sin(angle0), ct0 = std::cos(angle0);
  const double spatial_bin = f->magnif * sigma + VL_EPSILON_D;  // SBP
  const int radius =
      static_cast<int>(std::floor(std::sqrt(2.0) * spatial_bin * (kBins + 1) / 2.0 + 0.5));
  std::memset(descriptor, 0, sizeof(float) * kBins * kBins * kAngles);
  if (k.o != f->o_cur || xi < 0 || xi >= w || yi < 0 || yi >= h - 1 || si < f->s_min + 1 ||
      si > f->s_max - 2) {
    return;
  }
  const float* grad = f->grad + 2 * (static_cast<size_t>(si - f->s_min - 1) * w * h +
                                     static_cast<size_t>(yi) * w + xi);
  const float window_sigma = static_cast<float>(f->windowSize);
  const double window_scale = 2.0 * window_sigma * window_sigma;
  const ExpTable& expn = FastExpn();
  // Bin (bx, by, bt) of the 4 x 4 x 8 histogram, bx and by in [-2, 2).
  float* centre = descriptor + (kBins / 2) * kBins * kAngles + (kBins / 2) * kAngles;
  const int x_begin = std::max(-radius, 1 - xi), x_end = std::min(radius, w - xi - 2);
  if (x_end < x_begin) return NormalizeDescriptor(descriptor);
  std::vector<float>& nx = Scratch().nx;
  std::vector<float>& ny = Scratch().ny;
  std::vector<double>& r2 = Scratch().r2;
  nx.resize(x_end - x_begin + 1);
  ny.resize(nx.size());
  r2.resize(nx.size());
  for (int dyi = std::max(-radius, 1 - yi); dyi <= std::min(radius, h - yi - 2); ++dyi) {
    const float dy = static_cast<float>(yi + dyi - y);
    // The sample's position in the descriptor's frame (bins) and its squared
    // distance over the window's 2 sigma^2, for the whole row (vectorised).
    const double sdy = st0 * dy, cdy = ct0 * dy;
    RotateRow(xi + x_begin - x, static_cast<int>(nx.size()), ct0, st0, sdy, cdy, spatial_bin,
              window_scale, nx.data(), ny.data(), r2.data());
    for (int dxi = x_begin; dxi <= x_end; ++dxi) {
      const int i = dxi - x_begin;
      const int binx = static_cast<int>(vl_floor_f(static_cast<float>(nx[i] - 0.5)));
      const int biny = static_cast<int>(vl_floor_f(static_cast<float>(ny[i] - 0.5)));
      // Samples whose eight bins all fall outside the grid add nothing.
      if (binx < -3 || binx > 1 || biny < -3 || biny > 1) continue;
      const float* g = grad + 2 * (static_cast<ptrdiff_t>(dyi) * w + dxi);
      const float mod = g[0];
      const float theta = vl_mod_2pi_f(static_cast<float>(g[1] - angle0));
      const float nt = static_cast<float>(kAngles * theta / (2 * VL_PI));
      const float win = static_cast<float>(expn(r2[i]));
      const int bint = static_cast<int>(vl_floor_f(nt));
      const float rbinx = static_cast<float>(nx[i] - (binx + 0.5));
      const float rbiny = static_cast<float>(ny[i] - (biny + 0.5));
      const float rbint = nt - bint;
      for (int ex = 0; ex < 2; ++ex) {
        for (int ey = 0; ey < 2; ++ey) {
          for (int et = 0; et < 2; ++et) {
            if (binx + ex >= -kBins / 2 && binx + ex < kBins / 2 && biny + ey >= -kBins / 2 &&
                biny + ey < kBins / 2) {
              const float weight = win * mod * std::abs(1 - ex - rbinx) * std::abs(1 - ey - rbiny) *
                                   std::abs(1 - et - rbint);
              centre[(bint + et) % kAngles + (biny + ey) * kBins * kAngles +
                     (binx + ex) * kAngles] += weight;
            }
          }
        }
      }
    }
  }
  NormalizeDescriptor(descriptor);
}

}  // namespace linecloud
