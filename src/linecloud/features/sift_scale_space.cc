#include "linecloud/features/sift_scale_space.h"

extern "C" {
#include <vl/mathop.h>
#include <vl/sift.h>
}

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <condition_variable>
#include <mutex>
#include <utility>

#include <sys/mman.h>

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
constexpr int kBlock = 64;  // columns per pass over the taps: eight vectors

// acc[x] = sum_i rows[i][x] * filter[i], i ascending from 0, each product and
// sum rounded: VLFeat's column filter on one output row, all columns at once
// (rows[i] = the input's row y - W + i), or its row filter (rows[i] = the
// padded row shifted by i).
LINECLOUD_TARGET_CLONES void FilterColumns(const float* const* rows, const float* filter, int taps,
                                           int n, float* acc) {
  int x = 0;
  // Eight independent sums in flight: the additions' latency hidden.
  for (; x + kBlock <= n; x += kBlock) {
    Floats8 a[kBlock / 8] = {};
    for (int i = 0; i < taps; ++i) {
      const Floats8* r = reinterpret_cast<const Floats8*>(rows[i] + x);
      const float c = filter[i];
      for (int v = 0; v < kBlock / 8; ++v) a[v] += r[v] * c;
    }
    Floats8* out = reinterpret_cast<Floats8*>(acc + x);
    for (int v = 0; v < kBlock / 8; ++v) out[v] = a[v];
  }
  for (; x + 8 <= n; x += 8) {
    Floats8 a = {};
    for (int i = 0; i < taps; ++i) a += *reinterpret_cast<const Floats8*>(rows[i] + x) * filter[i];
    *reinterpret_cast<Floats8*>(acc + x) = a;
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
void FillLevels(VlSiftFilt* f, int threads, const SiftDeadline& deadline) {
  const int w = f->octave_width, h = f->octave_height;
  for (int s = f->s_min + 1; s <= f->s_max; ++s) {
    StopAtSiftDeadline(deadline);
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

constexpr int32_t kMagnitudeBits = 0x7fffffff;  // & clears the sign: fabsf lane by lane

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
    const Floats8 abs_y = (Floats8)((Ints8)y & kMagnitudeBits) + VL_EPSILON_F;
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

// What VLFeat's descriptor computes for one sample before adding it to the
// histogram: the lower bins along x, y and angle and the sample's weight in
// each of the eight bins around it (x, y, angle offsets 0 or 1, angle
// fastest). bx = by = kOutside when no bin of the grid gets any.
constexpr int kOutside = -100;
struct RowSamples {
  std::vector<int32_t> bx, by, bt;
  std::vector<float> weights[8];  // [4 ex + 2 ey + et][sample]
};

// One row of samples (dx = x0 + i, i < n) of a descriptor window, eight at a
// time: VLFeat's arithmetic lane by lane (double where it computes in double,
// rounded to float where it stores floats, no fused operations). `grad`
// points to the row's first sample (modulus, angle pairs).
struct DescriptorFrame {
  double ct0, st0, angle0, spatial_bin, window_scale;
};
LINECLOUD_TARGET_CLONES void SampleRow(const DescriptorFrame& frame, double x0, float dy,
                                       const float* grad, const ExpTable& expn, int n,
                                       RowSamples* out) {
  const int padded = (n + 7) / 8 * 8;
  if (out->bx.size() < static_cast<size_t>(padded)) {
    out->bx.resize(padded);
    out->by.resize(padded);
    out->bt.resize(padded);
    for (std::vector<float>& w : out->weights) w.resize(padded);
  }
  const float two_pi = static_cast<float>(2 * VL_PI);
  const double sdy = frame.st0 * dy, cdy = frame.ct0 * dy;
  const Floats8 zero = {}, one = zero + 1.0f;
  const Ints8 zero_ints = {};
  for (int i = 0; i < n; i += 8) {
    const int lanes = std::min(8, n - i);
    Floats8 mod = zero, angle = zero, dxf = zero;
    if (lanes == 8) {  // (modulus, angle) pairs apart
      const Floats8* pairs = reinterpret_cast<const Floats8*>(grad + 2 * i);
      mod = __builtin_shufflevector(pairs[0], pairs[1], 0, 2, 4, 6, 8, 10, 12, 14);
      angle = __builtin_shufflevector(pairs[0], pairs[1], 1, 3, 5, 7, 9, 11, 13, 15);
    } else {
      for (int j = 0; j < lanes; ++j) {
        mod[j] = grad[2 * (i + j)];
        angle[j] = grad[2 * (i + j) + 1];
      }
    }
    for (int j = 0; j < 8; ++j) dxf[j] = static_cast<float>(x0 + (i + j));
    const Doubles8 dx = __builtin_convertvector(dxf, Doubles8);
    const Floats8 nx = __builtin_convertvector((frame.ct0 * dx + sdy) / frame.spatial_bin, Floats8);
    const Floats8 ny =
        __builtin_convertvector((-frame.st0 * dx + cdy) / frame.spatial_bin, Floats8);
    // vl_floor_f of (float) (n - 0.5): truncation, less one below zero off the integers.
    const Floats8 sx =
        __builtin_convertvector(__builtin_convertvector(nx, Doubles8) - 0.5, Floats8);
    const Floats8 sy =
        __builtin_convertvector(__builtin_convertvector(ny, Doubles8) - 0.5, Floats8);
    Ints8 bx = __builtin_convertvector(sx, Ints8), by = __builtin_convertvector(sy, Ints8);
    bx += sx < __builtin_convertvector(bx, Floats8);  // true is -1
    by += sy < __builtin_convertvector(by, Floats8);
    // vl_mod_2pi_f of the angle to the keypoint's orientation.
    Floats8 theta =
        __builtin_convertvector(__builtin_convertvector(angle, Doubles8) - frame.angle0, Floats8);
    theta = theta > two_pi ? theta - two_pi : theta;
    theta = theta < 0 ? theta + two_pi : theta;
    for (int j = 0; j < lanes; ++j) {
      if (theta[j] < 0 || theta[j] > two_pi) {  // beyond one turn: VLFeat's loop
        theta[j] = vl_mod_2pi_f(static_cast<float>(grad[2 * (i + j) + 1] - frame.angle0));
      }
    }
    const Floats8 nt = __builtin_convertvector(
        __builtin_convertvector(8.0f * theta, Doubles8) / (2 * VL_PI), Floats8);
    const Ints8 bt = __builtin_convertvector(nt, Ints8);  // nt >= 0: floor
    const Floats8 rx = __builtin_convertvector(
        __builtin_convertvector(nx, Doubles8) - (__builtin_convertvector(bx, Doubles8) + 0.5),
        Floats8);
    const Floats8 ry = __builtin_convertvector(
        __builtin_convertvector(ny, Doubles8) - (__builtin_convertvector(by, Doubles8) + 0.5),
        Floats8);
    const Floats8 rt = nt - __builtin_convertvector(bt, Floats8);
    // fast_expn of the squared distance over the window's 2 sigma^2.
    const Doubles8 r2 = __builtin_convertvector(nx * nx + ny * ny, Doubles8) / frame.window_scale;
    Floats8 win = zero;
    for (int j = 0; j < lanes; ++j) {
      win[j] = static_cast<float>(expn(r2[j]));
    }
    // win * mod * |1 - ex - rx| * |1 - ey - ry| * |1 - et - rt|, left to right.
    const Floats8 w0 = win * mod;
    const Floats8 ax[2] = {(Floats8)((Ints8)(one - rx) & kMagnitudeBits),
                           (Floats8)((Ints8)(zero - rx) & kMagnitudeBits)};
    const Floats8 ay[2] = {(Floats8)((Ints8)(one - ry) & kMagnitudeBits),
                           (Floats8)((Ints8)(zero - ry) & kMagnitudeBits)};
    const Floats8 at[2] = {(Floats8)((Ints8)(one - rt) & kMagnitudeBits),
                           (Floats8)((Ints8)(zero - rt) & kMagnitudeBits)};
    Floats8 w[8];
    for (int ex = 0; ex < 2; ++ex) {
      for (int ey = 0; ey < 2; ++ey) {
        const Floats8 wxy = w0 * ax[ex] * ay[ey];
        w[4 * ex + 2 * ey] = wxy * at[0];
        w[4 * ex + 2 * ey + 1] = wxy * at[1];
      }
    }
    // Samples whose eight bins all fall outside the grid add nothing.
    const Ints8 inside = (bx >= -3) & (bx <= 1) & (by >= -3) & (by <= 1);
    const Ints8 outside = zero_ints + kOutside;
    *reinterpret_cast<Ints8*>(out->bx.data() + i) = inside ? bx : outside;
    *reinterpret_cast<Ints8*>(out->by.data() + i) = by;
    *reinterpret_cast<Ints8*>(out->bt.data() + i) = bt;
    for (int c = 0; c < 8; ++c) *reinterpret_cast<Floats8*>(out->weights[c].data() + i) = w[c];
  }
}

// The columns [first, last] of [begin, end] (offsets from the keypoint's
// pixel, `offset` = its position within that pixel) whose samples of the row
// dy can fall within the descriptor's 4 x 4 bins: |n| < 2.5 bins along both
// of the rotated axes, plus a margin of 0.01 bins and one column.
std::pair<int, int> GridColumns(const DescriptorFrame& frame, double offset, float dy, int begin,
                                int end) {
  const double reach = (2.5 + 0.01) * frame.spatial_bin;
  double lo = -1e300, hi = 1e300;  // dx bounds
  // Each rotated coordinate is a * dx + b: within [-reach, reach].
  const auto bound = [&](double a, double b) {
    if (std::abs(a) < 1e-9) {
      if (std::abs(b) > reach) lo = 1, hi = 0;
      return;
    }
    double u = (-reach - b) / a, v = (reach - b) / a;
    if (u > v) std::swap(u, v);
    lo = std::max(lo, u);
    hi = std::min(hi, v);
  };
  bound(frame.ct0, frame.st0 * dy);
  bound(-frame.st0, frame.ct0 * dy);
  if (lo > hi) return {1, 0};
  // dx = dxi - offset.
  const int first = static_cast<int>(std::max<double>(begin, std::floor(lo + offset) - 1));
  const int last = static_cast<int>(std::min<double>(end, std::ceil(hi + offset) + 1));
  return {first, last};
}

}  // namespace

namespace {

constexpr size_t kHugePage = size_t{2} << 20;
constexpr size_t kMaxPooledBytes = size_t{2} << 30;

// What a mapping of `bytes` usable bytes costs: rounded to huge pages, plus
// one for the alignment.
size_t MappedBytes(size_t bytes) {
  return (bytes + kHugePage - 1) / kHugePage * kHugePage + kHugePage;
}

// Scale-space buffers given back by finished extractions, for the next ones.
// Mapping afresh each time cost page faults and zeroing of ~550 MB per
// 1.6 MP photo — in a virtual machine also the host's first touch of memory:
// 1.25 s instead of 0.73 s for a run on cold memory. At most 2 GB are kept
// (three such photos); the buffers are written before they are read.
// With a limit (SetSiftMemoryLimit), reserved + pooled <= limit at all times:
// a reservation waits for room, pooled buffers are unmapped to make it.
class MappingPool {
 public:
  static MappingPool& Get() {
    static MappingPool* pool = new MappingPool;  // outlives every SiftFilter
    return *pool;
  }

  void SetLimit(size_t bytes) {
    std::lock_guard<std::mutex> lock(mutex_);
    limit_ = bytes;
    if (limit_) Evict(limit_ - std::min(limit_, reserved_));
  }

  SiftMemoryUse Use() {
    std::lock_guard<std::mutex> lock(mutex_);
    return {limit_, reserved_, pooled_};
  }

  // Reserves `bytes` under the limit (at once without one), unless the limit
  // alone is smaller — also a limit lowered while it waits (an outsider's
  // photo waited forever for room a lowered limit could never give) — or
  // `deadline` passes or its caller asks to stop first (polled every 50 ms,
  // the lock released: the caller's stop may take Python's GIL).
  enum class Reservation { kMade, kOverLimit, kTimedOut, kStopped };
  Reservation Reserve(size_t bytes, const SiftDeadline& deadline, size_t* limit) {
    using Clock = std::chrono::steady_clock;
    std::unique_lock<std::mutex> lock(mutex_);
    const auto over = [&] { return limit_ && bytes > limit_; };
    const auto fits = [&] { return !limit_ || reserved_ + bytes <= limit_; };
    while (true) {
      *limit = limit_;
      if (over()) return Reservation::kOverLimit;
      if (fits()) break;
      const Clock::time_point slice = Clock::now() + std::chrono::milliseconds(50);
      const Clock::time_point until = deadline.at ? std::min(*deadline.at, slice) : slice;
      room_.wait_until(lock, until, [&] { return over() || fits(); });
      if (over() || fits()) continue;
      if (deadline.at && Clock::now() >= *deadline.at) return Reservation::kTimedOut;
      if (deadline.stop) {
        lock.unlock();
        const bool stop = deadline.stop();
        lock.lock();
        if (stop) return Reservation::kStopped;
      }
    }
    reserved_ += bytes;
    if (limit_) Evict(limit_ - reserved_);
    return Reservation::kMade;
  }

  // A 2 MB-aligned mapping of at least `bytes` (advised to use huge pages)
  // of at most `budget` mapped bytes: the smallest pooled one that fits
  // and is at most twice as large (a photo's large buffers are not spent on a
  // small one's), or a new one; data is nullptr if none can be made.
  Mapping Take(size_t bytes, size_t budget) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      size_t best = free_.size();
      for (size_t i = 0; i < free_.size(); ++i) {
        const size_t have = free_[i].bytes;
        if (have >= bytes && have <= 2 * bytes + kHugePage && free_[i].mapped <= budget &&
            (best == free_.size() || have < free_[best].bytes)) {
          best = i;
        }
      }
      if (best < free_.size()) {
        const Mapping m = free_[best];
        free_.erase(free_.begin() + static_cast<ptrdiff_t>(best));
        pooled_ -= m.mapped;
        return m;
      }
    }
    const size_t mapped = MappedBytes(bytes);
    if (mapped > budget) return {};
    void* base = mmap(nullptr, mapped, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (base == MAP_FAILED) return {};
    // The first huge-page boundary inside the mapping: whole 2 MB pages follow.
    const uintptr_t aligned =
        (reinterpret_cast<uintptr_t>(base) + kHugePage - 1) & ~(uintptr_t{kHugePage} - 1);
    const size_t usable = mapped - kHugePage;
#ifdef MADV_HUGEPAGE
    madvise(reinterpret_cast<void*>(aligned), usable, MADV_HUGEPAGE);
#endif
    return {base, mapped, reinterpret_cast<float*>(aligned), usable};
  }

  // A filter's mappings back, then its reservation.
  void Give(const std::vector<Mapping>& mappings, size_t reserved) {
    std::vector<Mapping> unmap;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      reserved_ -= reserved;
      for (const Mapping& m : mappings) {
        const bool room = pooled_ + m.mapped <= kMaxPooledBytes &&
                          (!limit_ || reserved_ + pooled_ + m.mapped <= limit_);
        if (room) {
          free_.push_back(m);
          pooled_ += m.mapped;
        } else {
          unmap.push_back(m);
        }
      }
    }
    room_.notify_all();
    for (const Mapping& m : unmap) munmap(m.base, m.mapped);
  }

 private:
  // Unmaps pooled buffers, largest first, until at most `keep` bytes stay.
  void Evict(size_t keep) {
    std::sort(free_.begin(), free_.end(),
              [](const Mapping& a, const Mapping& b) { return a.mapped < b.mapped; });
    while (pooled_ > keep && !free_.empty()) {
      munmap(free_.back().base, free_.back().mapped);
      pooled_ -= free_.back().mapped;
      free_.pop_back();
    }
  }

  std::mutex mutex_;
  std::condition_variable room_;
  std::vector<Mapping> free_;
  size_t pooled_ = 0;    // mapped bytes in free_
  size_t reserved_ = 0;  // by live filters
  size_t limit_ = 0;     // 0: none
};

}  // namespace

void StopAtSiftDeadline(const SiftDeadline& deadline) {
  if (deadline.at && std::chrono::steady_clock::now() >= *deadline.at) {
    throw DeadlinePassed("the request's deadline passed during SIFT");
  }
  if (deadline.stop && deadline.stop()) throw DeadlinePassed("stopped by the caller during SIFT");
}

void SetSiftMemoryLimit(size_t bytes) { MappingPool::Get().SetLimit(bytes); }

SiftMemoryUse SiftMemoryInUse() { return MappingPool::Get().Use(); }

size_t SiftFilterBytes(int width, int height, int octaves, int levels, int first_octave) {
  const auto pixels_at = [&](int o) {
    return static_cast<size_t>(std::max(ShiftLeft(width, -o), 0)) *
           static_cast<size_t>(std::max(ShiftLeft(height, -o), 0));
  };
  const size_t pixels = pixels_at(first_octave);
  const size_t kept = static_cast<size_t>(levels) + 3;  // VLFeat's s_min = -1 .. s_max = levels + 1
  const size_t f = sizeof(float);
  // temp, octave, DoG, and the larger of VLFeat's one gradient buffer or ours per octave.
  size_t bytes = MappedBytes(f * pixels) + MappedBytes(f * pixels * kept) +
                 MappedBytes(f * pixels * (kept - 1));
  size_t ours = 0;
  for (int o = first_octave; o < first_octave + octaves; ++o) {
    ours += MappedBytes(f * 2 * static_cast<size_t>(levels) * pixels_at(o));
  }
  return bytes + std::max(ours, MappedBytes(f * 2 * pixels * (kept - 1)));
}

SiftFilter::SiftFilter(int width, int height, int octaves, int levels, int first_octave,
                       bool vlfeat_gradients, SiftDeadline wait_until) {
  const size_t need = SiftFilterBytes(width, height, octaves, levels, first_octave);
  size_t limit = 0;
  switch (MappingPool::Get().Reserve(need, wait_until, &limit)) {
    case MappingPool::Reservation::kMade:
      break;
    case MappingPool::Reservation::kOverLimit:
      Fail("SIFT on a {}x{} image needs {} MB of scale space, more than the memory limit of {} MB",
           width, height, need >> 20, limit >> 20);
    case MappingPool::Reservation::kTimedOut:
      throw DeadlinePassed(fmt::format(
          "the deadline passed while SIFT waited for {} MB of scale space (limit {} MB)",
          need >> 20, limit >> 20));
    case MappingPool::Reservation::kStopped:
      throw DeadlinePassed("stopped by the caller while SIFT waited for memory");
  }
  reserved_ = need;
  bounded_ = limit != 0;
  filter_ = vl_sift_new(width, height, octaves, levels, first_octave);
  if (!filter_) {
    Release();
    Fail("VLFeat could not set up SIFT for a {}x{} image", width, height);
  }
  VlSiftFilt* f = filter_;
  const size_t pixels = static_cast<size_t>(ShiftLeft(width, -first_octave)) *
                        static_cast<size_t>(ShiftLeft(height, -first_octave));
  const size_t levels_kept = static_cast<size_t>(f->s_max - f->s_min + 1);
  // VLFeat's own sizes (vl_sift_new), its allocations given back.
  vl_free(f->temp);
  vl_free(f->octave);
  vl_free(f->dog);
  vl_free(f->grad);
  f->temp = f->octave = f->dog = f->grad = nullptr;
  f->temp = Allocate(pixels);
  f->octave = Allocate(pixels * levels_kept);
  f->dog = Allocate(pixels * (levels_kept - 1));
  if (vlfeat_gradients) f->grad = Allocate(2 * pixels * (levels_kept - 1));
}

SiftFilter::~SiftFilter() { Release(); }

void SiftFilter::Release() {
  if (filter_) {
    filter_->temp = filter_->octave = filter_->dog = filter_->grad = nullptr;
    vl_sift_delete(filter_);
    filter_ = nullptr;
  }
  MappingPool::Get().Give(mappings_, reserved_);
  mappings_.clear();
  reserved_ = mapped_ = 0;
}

float* SiftFilter::Allocate(size_t floats) {
  // Under a limit, a pooled buffer may not cost more than a new one: the
  // reservation (SiftFilterBytes) counts new ones.
  const size_t cost = MappedBytes(floats * sizeof(float));
  const bool fits = !bounded_ || mapped_ + cost <= reserved_;
  const Mapping m =
      fits ? MappingPool::Get().Take(floats * sizeof(float), bounded_ ? cost : SIZE_MAX)
           : Mapping{};
  if (!m.data) {
    const size_t mb = (floats * sizeof(float)) >> 20;
    Release();  // also when the constructor throws (no destructor runs then)
    Fail("could not map {} MB for SIFT's scale space", mb);
  }
  mappings_.push_back(m);
  mapped_ += m.mapped;
  return m.data;
}

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

bool ProcessFirstOctave(VlSiftFilt* f, const float* image, int threads,
                        const SiftDeadline& deadline) {
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
  FillLevels(f, threads, deadline);
  return true;
}

bool ProcessNextOctave(VlSiftFilt* f, int threads, const SiftDeadline& deadline) {
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
  FillLevels(f, threads, deadline);
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
  const int n = x_end - x_begin + 1;
  const DescriptorFrame frame{ct0, st0, angle0, spatial_bin, window_scale};
  thread_local RowSamples samples;
  for (int dyi = std::max(-radius, 1 - yi); n > 0 && dyi <= std::min(radius, h - yi - 2); ++dyi) {
    const float dy = static_cast<float>(yi + dyi - y);
    // VLFeat visits the whole square; only the columns of the rotated grid
    // (and a margin far wider than rounding) can reach a bin.
    const auto [first, last] = GridColumns(frame, x - xi, dy, x_begin, x_end);
    if (first > last) continue;
    const int m = last - first + 1;
    SampleRow(frame, xi + first - x, dy, grad + 2 * (static_cast<ptrdiff_t>(dyi) * w + first), expn,
              m, &samples);
    // The samples added in VLFeat's order, each to its eight bins (x, y, angle).
    for (int i = 0; i < m; ++i) {
      const int bx = samples.bx[i], by = samples.by[i], bt = samples.bt[i];
      if (bx == kOutside) continue;
      // bt >= 0, so & 7 is VLFeat's % 8; inside the grid all eight bins exist.
      const int t0 = bt & 7, t1 = (bt + 1) & 7;
      if (bx >= -2 && bx <= 0 && by >= -2 && by <= 0) {
        float* bin = centre + by * kBins * kAngles + bx * kAngles;
        for (int e = 0; e < 4; ++e) {  // e = 2 ex + ey
          float* b = bin + (e & 1) * kBins * kAngles + (e >> 1) * kAngles;
          b[t0] += samples.weights[2 * e][i];
          b[t1] += samples.weights[2 * e + 1][i];
        }
        continue;
      }
      for (int ex = 0; ex < 2; ++ex) {
        if (bx + ex < -kBins / 2 || bx + ex >= kBins / 2) continue;
        for (int ey = 0; ey < 2; ++ey) {
          if (by + ey < -kBins / 2 || by + ey >= kBins / 2) continue;
          float* bin = centre + (by + ey) * kBins * kAngles + (bx + ex) * kAngles;
          bin[t0] += samples.weights[4 * ex + 2 * ey][i];
          bin[t1] += samples.weights[4 * ex + 2 * ey + 1][i];
        }
      }
    }
  }
  NormalizeDescriptor(descriptor);
}

}  // namespace linecloud
