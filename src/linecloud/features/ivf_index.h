// An inverted-file index of SIFT descriptor bytes for matching photos to
// large maps (Sivic & Zisserman, "Video Google", ICCV 2003; Jégou, Douze &
// Schmid, "Product quantization for nearest neighbor search", TPAMI 2011, whose
// IVF scheme FAISS implements): the map's descriptors are clustered by k-means
// (FAISS's Clustering, spherical, fixed seed) into `nlist` cells and stored
// cell by cell as their own bytes; a query's two nearest descriptors by inner
// product are searched among the rows of its `nprobe` nearest cells.
//
// Written because FAISS's own IVF (Debian's build is SSE-only) and the other
// libraries missed the target on real descriptors (docs/fast_photo.md): the
// scan here is exact integer arithmetic on the bytes with AVX2 / AVX-512
// kernels picked at run time (a portable one elsewhere), and queries are
// scanned cell by cell so that each cell's rows are read once per batch. The
// coarse step is a BLAS matrix product (FAISS's flat inner-product index).
//
// Search results do not depend on the thread count or batch: ties between
// equal dot products go to the smaller row.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace linecloud {

class IvfIndex {
 public:
  // Clusters `descriptors` (rows of 128 bytes, at least 2) into `nlist` cells
  // (clamped to [1, rows / 16]) on `threads` threads.
  static std::unique_ptr<IvfIndex> Build(std::span<const uint8_t> descriptors, int nlist,
                                         int threads);
  // Reads what Serialize wrote for `rows` descriptors; nullptr when the data
  // is not a consistent index of that size.
  static std::unique_ptr<IvfIndex> Deserialize(std::string_view data, size_t rows);
  ~IvfIndex();

  std::string Serialize() const;
  size_t size() const { return ids_.size(); }
  int nlist() const { return nlist_; }

  // For each query row, the rows of the two largest inner products (ids[2i],
  // ids[2i+1]; -1 when its cells hold fewer), among the rows of its `nprobe`
  // nearest cells. One thread.
  void Search(std::span<const uint8_t> queries, int nprobe, int64_t* ids) const;

  // The instruction set the scan uses on this machine ("avx512bw", "avx2" or
  // "portable").
  static const char* Kernel();
  // The scan kernel `kernel` (one this CPU runs) on `n` rows: for tests.
  static void DotsWith(const std::string& kernel, const int16_t* query, const uint8_t* rows,
                       size_t n, int32_t* out);
  // The coarse step's top-k selection with kernel `kernel`: the indices of the
  // k largest of `n` values, largest first, the earlier index first among
  // equals. For tests.
  static std::vector<uint32_t> TopKWith(const std::string& kernel, const float* values, int n,
                                        int k);

 private:
  IvfIndex() = default;
  void MakeCoarse();

  int nlist_ = 0;
  std::vector<float> centroids_;   // nlist x 128, unit length
  std::vector<uint32_t> offsets_;  // nlist + 1: cell c holds stored rows [offsets[c], offsets[c+1])
  std::vector<uint32_t> ids_;      // stored row -> row of the descriptors given
  std::vector<uint8_t> rows_;      // the descriptors, cell by cell
  struct Coarse;
  std::unique_ptr<Coarse> coarse_;  // FAISS's flat index of the centroids
};

}  // namespace linecloud
