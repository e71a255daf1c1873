// An approximate nearest-neighbour index of a map's descriptors for maps too
// large for exact matching: hnswlib's hierarchical navigable small-world
// graph (Malkov & Yashunin, TPAMI 2020; Debian's libhnswlib-dev). The first
// candidate measured by `linecloud bench match` (docs/image.md); FLANN and FAISS
// are still to be measured against it, and localize does not use it yet. The index only
// proposes the two nearest neighbours; their descriptor angles are computed
// exactly and the same ratio and distance tests as MatchDescriptors decide.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "linecloud/features/matching.h"

namespace linecloud {

struct DescriptorIndexOptions {
  int graph_degree = 16;        // hnswlib M
  int construction_ef = 100;    // hnswlib ef_construction
  int search_ef = 64;           // candidates kept while searching (≥ 2)
  int threads = 1;              // for building

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
