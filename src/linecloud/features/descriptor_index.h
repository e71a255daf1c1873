// An approximate nearest-neighbour index of a map's descriptors for maps too
// large for exact matching: FLANN's randomised kd-trees (Muja & Lowe, VISAPP
// 2009 / TPAMI 2014; Debian's libflann-dev), chosen over hnswlib by a measured
// comparison (docs/image.md: at 100 000 descriptors FLANN found 0.99 of the
// exact ratio-test matches in 0.4 s for 8 000 queries, hnswlib 0.90 in 2.1 s).
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

  // Loads an index saved by Save for the same descriptors; nullptr when the
  // file is missing, stale (other descriptors) or unreadable.
  static std::unique_ptr<DescriptorIndex> Load(const std::string& path,
                                               std::span<const uint8_t> descriptors,
                                               const DescriptorIndexOptions& options);
  void Save(const std::string& path) const;

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
