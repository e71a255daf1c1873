// An approximate nearest-neighbour index of a map's descriptors for maps too
// large for exact matching: FLANN's randomised kd-trees (Muja & Lowe, VISAPP
// 2009 / TPAMI 2014; Debian's libflann-dev), chosen over hnswlib by a measured
// comparison (docs/image.md: at 100 000 descriptors FLANN found 0.99 of the
// exact ratio-test matches in 0.4 s for 8 000 queries, hnswlib 0.90 in 2.1 s).
// The index is built from a fixed seed (the same trees, and so the same
// matches, on every run and thread) without touching the program's rand().
// The index only proposes the two nearest neighbours; their descriptor angles
// are computed exactly and the same ratio and distance tests as
// MatchDescriptors decide.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "linecloud/features/matching.h"

namespace linecloud {

struct DescriptorIndexOptions {
  int trees = 4;    // randomised kd-trees
  int checks = 64;  // leaves visited per query (more: higher recall, slower)
  int threads = 1;  // reserved (FLANN builds on one thread)

  void Check() const;
};

class DescriptorIndex {
 public:
  // Indexes `descriptors` (rows of 128 bytes), kept by reference: they must
  // outlive the index.
  DescriptorIndex(std::span<const uint8_t> descriptors, const DescriptorIndexOptions& options);
  ~DescriptorIndex();
  DescriptorIndex(const DescriptorIndex&) = delete;
  DescriptorIndex& operator=(const DescriptorIndex&) = delete;

  // Loads an index saved by Save for the same descriptors under the same
  // `mac_key`; nullptr when the file is missing, stale (other descriptors),
  // unreadable, too large, or not authenticated by `mac_key` (a keyed BLAKE2b
  // over the whole file: a cache is untrusted input, and FLANN's reader trusts
  // what it reads, so only an index this key's holder wrote is parsed).
  static std::unique_ptr<DescriptorIndex> Load(const std::string& path,
                                               std::span<const uint8_t> descriptors,
                                               const DescriptorIndexOptions& options,
                                               std::span<const uint8_t, 32> mac_key);
  // Writes the index atomically, authenticated with `mac_key` (a secret of the
  // user's, e.g. KeyStore::CacheSecret()).
  void Save(const std::string& path, std::span<const uint8_t, 32> mac_key) const;

  size_t size() const;

  // Like MatchDescriptors (cross_check is not supported here).
  std::vector<DescriptorMatch> Match(std::span<const uint8_t> query,
                                     const DescriptorMatchOptions& options) const;

 private:
  DescriptorIndex() = default;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace linecloud
