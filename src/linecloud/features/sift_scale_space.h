// VLFeat's SIFT scale space computed faster, to the same bits: the Gaussian
// octaves (the doubled image, the smoothing of each level, the halving to the
// next octave) and the gradient images (modulus and angle) that VLFeat's
// `vl_sift_process_first_octave`, `vl_sift_process_next_octave` and its
// internal gradient update compute. They fill the same buffers of a
// `VlSiftFilt`, so VLFeat's own detector (`vl_sift_detect`), orientations and
// descriptors then run on them unchanged.
//
// VLFeat (0.9.21, Debian's build) smooths with a scalar column filter that
// takes 60 % of COLMAP's CPU extraction; here each output pixel gets the same
// float operations in the same order (products and sums rounded one by one,
// taps in ascending order, borders continued), vectorised across pixels and
// split over threads by rows. Contracting a product and a sum into one fused
// operation would change the bits: this file is compiled with
// -ffp-contract=off. The tests compare every pixel of every level with
// VLFeat's (sift_scale_space_test.cc).
#pragma once

#include <chrono>
#include <cstddef>
#include <functional>
#include <optional>
#include <utility>
#include <vector>

typedef struct _VlSiftFilt VlSiftFilt;
typedef struct _VlSiftKeypoint VlSiftKeypoint;

namespace linecloud {

// A memory mapping for SIFT's scale space: `data` (2 MB aligned, `bytes`
// long) inside [base, base + mapped).
struct Mapping {
  void* base = nullptr;
  size_t mapped = 0;
  float* data = nullptr;
  size_t bytes = 0;
};

// When the caller stops waiting (none: run to the end), and whether it asks
// to stop (polled on the extracting thread between steps: Python's Ctrl-C).
struct SiftDeadline {
  std::optional<std::chrono::steady_clock::time_point> at;
  std::function<bool()> stop;

  SiftDeadline() = default;
  SiftDeadline(std::optional<std::chrono::steady_clock::time_point> at_,  // NOLINT: implicit
               std::function<bool()> stop_ = {})
      : at(at_), stop(std::move(stop_)) {}
};
// Throws DeadlinePassed once `deadline` has passed or its caller asks to stop.
void StopAtSiftDeadline(const SiftDeadline& deadline);

// The scale space's memory, process-wide: every SiftFilter reserves the bytes
// its image needs (SiftFilterBytes) before it maps anything, and a reservation
// waits until it fits under the limit — pooled buffers of finished filters
// are given back to the system to make room. With a limit, the scale space of
// all extractions together (live and pooled) never exceeds it. 0: no limit
// (the default; the pool then keeps at most 2 GB).
void SetSiftMemoryLimit(size_t bytes);
struct SiftMemoryUse {
  size_t limit = 0;     // 0: none
  size_t reserved = 0;  // by live filters
  size_t pooled = 0;    // mapped, kept for the next filters
};
SiftMemoryUse SiftMemoryInUse();

// An upper bound of the bytes a SiftFilter of these arguments maps, the
// per-octave gradient buffers of our scale space included (sift.cc).
size_t SiftFilterBytes(int width, int height, int octaves, int levels, int first_octave);

// A VLFeat SIFT filter (vl_sift_new's) whose image buffers — hundreds of MB
// for a doubled photo — are anonymous mappings advised to use huge pages and
// kept in a process-wide pool (up to 2 GB) for the next filters: no page
// faults or zeroing once warm (a sixth of the extraction's time otherwise).
// VLFeat's one gradient buffer only with `vlfeat_gradients` (VLFeat's own
// code computes into it; ours keeps one per octave, see Allocate).
// The constructor reserves SiftFilterBytes under the memory limit, waiting
// until `wait_until` at most (then DeadlinePassed); a filter that alone
// exceeds the limit is an Error naming both.
class SiftFilter {
 public:
  SiftFilter(int width, int height, int octaves, int levels, int first_octave,
             bool vlfeat_gradients, SiftDeadline wait_until = {});
  ~SiftFilter();
  SiftFilter(const SiftFilter&) = delete;
  SiftFilter& operator=(const SiftFilter&) = delete;
  VlSiftFilt* get() const { return filter_; }
  // Another buffer of `floats` floats, valid while this lives. Its contents
  // are undefined (a pooled buffer keeps an earlier image's values).
  float* Allocate(size_t floats);

 private:
  void Release();
  VlSiftFilt* filter_ = nullptr;
  std::vector<Mapping> mappings_;
  size_t reserved_ = 0;   // bytes reserved under the memory limit
  size_t mapped_ = 0;     // of which mapped by mappings_
  bool bounded_ = false;  // a limit held when it was reserved: mappings stay within it
};

// VLFeat's Gaussian filter of standard deviation `sigma`: 2W + 1 taps,
// W = max(ceil(4 sigma), 1), normalised to sum 1 in float.
std::vector<float> VlFeatGaussianFilter(double sigma);

// `out` = `in` (width x height, row-major) smoothed by the separable filter
// `filter` (odd length, symmetric), columns first, borders continued: VLFeat's
// `_vl_sift_smooth`. `in` and `out` must not overlap.
void SmoothGaussian(const float* in, float* out, int width, int height,
                    const std::vector<float>& filter, int threads);

// The first octave of `image` (the filter's width x height, values in
// [0, 1]) into `sift`'s octave buffer, as `vl_sift_process_first_octave`.
// Returns false when the filter has no octave. First octaves below -1 are
// refused: VLFeat's second doubling reads non-square images with the sides
// swapped, which this does not reproduce (ExtractSiftColmap leaves them to
// VLFeat).
// With a deadline: DeadlinePassed between levels once it has passed.
bool ProcessFirstOctave(VlSiftFilt* sift, const float* image, int threads,
                        const SiftDeadline& deadline = {});
// The next octave, as `vl_sift_process_next_octave`; false after the last.
bool ProcessNextOctave(VlSiftFilt* sift, int threads, const SiftDeadline& deadline = {});
// The current octave's gradient images, as VLFeat computes them on its first
// orientation or descriptor call; afterwards VLFeat's orientation and
// descriptor calls of this octave only read the filter (any thread).
void UpdateGradients(VlSiftFilt* sift, int threads);

// Keypoint `k`'s descriptor at orientation `angle` (radians) from the current
// octave's gradients, in VLFeat's bin order: `vl_sift_calc_keypoint_descriptor`
// to the bit, ~4x faster — the same float and double operations sample by
// sample, but the samples whose weight falls outside the 4 x 4 grid (half of
// VLFeat's square window) skipped before their weight is computed. All zero
// where VLFeat leaves the output untouched (a keypoint outside the octave).
void DescribeKeypoint(const VlSiftFilt* sift, const VlSiftKeypoint& k, double angle,
                      float* descriptor);

}  // namespace linecloud
