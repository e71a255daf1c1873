// What a key has released, kept beside the key in the key store so that a
// later version of the model keeps "one point, one line" (identity.h): for
// each released line its direction and moment in the ledger's frame (the
// frame of the first release), the observations its point was seen in, and
// the centres of the images that saw them (to align a re-run reconstruction,
// which has another gauge, with the released one).
//
// Observations and images are named by keyed hashes (SipHash-2-4 under a
// subkey of the model's key) of (image features, keypoint index) and of the
// image's name and of its features (its first keypoints): the ledger holds no point and no image
// name. Each line also keeps a 64-bit keyed sketch of its point's descriptor (DescriptorSketcher:
// signs of 64 keyed random projections, whose Hamming distance tracks the descriptors' angle),
// which tells a rebuilt version's points their own released line among the lines passing near
// them; a sketch says less than the descriptor a published map carries. Its lines are the released
// lines (what the published maps hold anyway); the image centres are the one geometric addition,
// kept as private as the key (mode 0600, in the store).
//
// File: "linecloud-release-ledger 2\n", then three little-endian u64 counts
// (lines, observations, images), the released scene's diagonal (f64), then the lines (v, w: 6
// float64; compact index: u8; descriptor sketch: u64, 0 for none), the observations (hash u64, line
// u32), the images (hash u64, centre: 3 float64), then a BLAKE2b-256 of everything before it. Read
// header → counts → size check → body → checksum: a damaged ledger is an error naming the file,
// never a silently smaller one. Version-1 ledgers (no sketches) are read as version 2 with every
// sketch 0.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/plucker.h"
#include "linecloud/lifting/key.h"

namespace linecloud {

struct ReleaseLedger {
  std::vector<PluckerLine> lines;  // released lines, ledger frame
  std::vector<uint8_t> compact;    // their compact direction index (compact256 keys)
  std::vector<uint64_t> sketch;    // their point's descriptor sketch, 0: none
  // The largest scene diagonal released (ledger frame; 0: unknown): a later
  // version that is a piece of the scene measures same_place by it.
  double diagonal = 0;
  // (observation hash, line index), sorted by hash, hashes unique.
  std::vector<std::pair<uint64_t, uint32_t>> observations;
  // (image hash, camera centre in the ledger frame), sorted by hash, unique.
  std::vector<std::pair<uint64_t, Eigen::Vector3d>> images;

  bool empty() const { return lines.empty(); }
  // The line an observation was released with, or -1 (through the hash
  // index when Index() was called since `observations` last changed).
  int64_t LineOfObservation(uint64_t hash) const;
  // An open-addressing index of `observations` (the hashes are keyed SipHash
  // values, uniform already): O(1) lookups for a million-point re-lift.
  void Index();
  const Eigen::Vector3d* ImageCentre(uint64_t hash) const;

 private:
  std::vector<uint64_t> index_hash_;
  std::vector<uint32_t> index_line_;  // line + 1; 0: empty slot
  size_t indexed_ = 0;                // observations.size() when indexed
};

// The keyed hashes naming images and observations in a ledger.
class ObservationHasher {
 public:
  explicit ObservationHasher(const LiftingKey& key);
  uint64_t Image(std::string_view name) const;
  // An observation: the image (by the hash of its features, see
  // ImageFeatures, not its name or id, which versions change) and the
  // keypoint's index.
  uint64_t Observation(uint64_t image_hash, uint32_t point2D_idx) const;
  // An image by its features: its keypoint count and first 16 keypoints
  // (`first`) rounded to pixels; by its file name when it has fewer.
  uint64_t ImageFeatures(std::string_view name, size_t count,
                         std::span<const Eigen::Vector2d> first) const;

 private:
  unsigned char key_[16];
};

// Keyed SimHash of a descriptor (Charikar, STOC 2002): bit b is the sign of
// the descriptor's projection on a keyed random ±1 vector; two descriptors at
// angle θ differ in a bit with probability ≈ θ/π. Never 0 (0 means none).
class DescriptorSketcher {
 public:
  DescriptorSketcher(const LiftingKey& key, int dim);
  uint64_t Sketch(std::span<const uint8_t> descriptor) const;

 private:
  int dim_;
  std::vector<int8_t> signs_;  // 64 x dim
};

// Bits of two sketches that differ; 64 when either is none.
int SketchDistance(uint64_t a, uint64_t b);

// FINGERPRINT.ledger in the key store `dir`.
std::string LedgerPath(const std::string& dir, const LiftingKey::Id& fingerprint);
// An absent file is an empty ledger; a damaged one throws Error naming it.
ReleaseLedger ReadLedger(const std::string& path);
// Atomically, mode 0600.
void WriteLedger(const std::string& path, const ReleaseLedger& ledger);

}  // namespace linecloud
