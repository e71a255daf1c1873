// An approximate nearest-neighbour index of a map's descriptors for maps too
// large for exact matching. Four kinds, compared on real SIFT descriptors by
// `linecloud bench match --real` (docs/fast_photo.md) — the default is the
// measured winner:
//   - our inverted file of the bytes with AVX2 / AVX-512 scans (ivf_index.h);
//   - FAISS's inverted file (Jégou, Douze & Schmid, TPAMI 2011; Johnson, Douze
//     & Jégou, "Billion-scale similarity search with GPUs", 2019): k-means
//     cells, the descriptors stored as their own bytes (8-bit direct), the
//     query scanned against the nprobe nearest cells by inner product;
//   - FAISS's and hnswlib's HNSW graphs (Malkov & Yashunin, TPAMI 2020;
//     hnswlib 0.6.2 over-reads one link past a node's list when it
//     prefetches — a peer for `bench match`, not for production);
//   - FLANN's randomised kd-trees (Muja & Lowe, VISAPP 2009 / TPAMI 2014).
// Every kind is built from fixed seeds (the same index, and so the same
// matches, on every run; searches are per query, so any thread count gives
// the same matches) without touching the program's rand(). The index only
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

enum class DescriptorIndexKind { kIvf, kFaissIvf, kFaissHnsw, kHnswlib, kFlann };

// "ivf", "faiss-ivf", "faiss-hnsw", "hnswlib", "flann"; throws Error naming `option`.
DescriptorIndexKind ParseDescriptorIndexKind(const std::string& name, const std::string& option);
const char* DescriptorIndexKindName(DescriptorIndexKind kind);

struct DescriptorIndexOptions {
  DescriptorIndexKind kind = DescriptorIndexKind::kIvf;
  // IVF (ours, FAISS's): cells (0: 4 sqrt(n), at most n / 32) and cells
  // scanned per query.
  int nlist = 0;
  int nprobe = 16;
  // HNSW (FAISS and hnswlib): links per node, candidate lists when building
  // and searching.
  int hnsw_m = 16;
  int ef_construction = 100;
  int ef_search = 64;
  // FLANN: randomised kd-trees and leaves visited per query.
  int trees = 4;
  int checks = 64;
  // Threads of a search (and of FAISS IVF's build); results do not depend on it.
  int threads = 1;

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

  DescriptorIndexKind kind() const;

  // Like MatchDescriptors (cross_check is not supported here). `threads`
  // overrides the options' when positive.
  std::vector<DescriptorMatch> Match(std::span<const uint8_t> query,
                                     const DescriptorMatchOptions& options, int threads = 0) const;

 private:
  DescriptorIndex() = default;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace linecloud
