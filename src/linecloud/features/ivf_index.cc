#include "linecloud/features/ivf_index.h"

// GCC 12's AVX-512 intrinsics read an uninitialised dummy operand (GCC bug
// 105593): its warning, not ours, is silenced in this file (clang has no such
// warning group).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include <immintrin.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>

#include <faiss/Clustering.h>
#include <faiss/IndexFlat.h>

#include "linecloud/features/omp_threads.h"
#include "linecloud/util/error.h"

// BLAS's single-precision matrix product (Fortran interface; FAISS links
// the BLAS it was built with, OpenBLAS on Debian).
extern "C" int sgemm_(const char* transa, const char* transb, const int* m, const int* n,
                      const int* k, const float* alpha, const float* a, const int* lda,
                      const float* b, const int* ldb, const float* beta, float* c, const int* ldc);

namespace linecloud {
namespace {

constexpr int kDim = 128;
constexpr char kMagic[] = "linecloud-ivf-u8-v1\n";

// Dot products of one query (as 16-bit integers) with `n` rows of bytes.
using DotKernel = void (*)(const int16_t* query, const uint8_t* rows, size_t n, int32_t* out);

void DotsPortable(const int16_t* q, const uint8_t* rows, size_t n, int32_t* out) {
  for (size_t r = 0; r < n; ++r) {
    const uint8_t* row = rows + r * kDim;
    int32_t s = 0;
    for (int i = 0; i < kDim; ++i) s += q[i] * row[i];
    out[r] = s;
  }
}

// 16 bytes widened to 16-bit lanes, multiplied pairwise with the query and
// summed to 32-bit (vpmaddwd): 8 steps per row. Products of bytes and bytes
// fit: 2 x 255 x 255 per lane, 128 x 255 x 255 per row.
__attribute__((target("avx2"))) void DotsAvx2(const int16_t* q, const uint8_t* rows, size_t n,
                                              int32_t* out) {
  __m256i qv[8];
  for (int k = 0; k < 8; ++k)
    qv[k] = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(q + 16 * k));
  for (size_t r = 0; r < n; ++r) {
    const uint8_t* row = rows + r * kDim;
    __m256i acc = _mm256_setzero_si256();
    for (int k = 0; k < 8; ++k) {
      const __m256i v =
          _mm256_cvtepu8_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(row + 16 * k)));
      acc = _mm256_add_epi32(acc, _mm256_madd_epi16(v, qv[k]));
    }
    __m128i s = _mm_add_epi32(_mm256_castsi256_si128(acc), _mm256_extracti128_si256(acc, 1));
    s = _mm_add_epi32(s, _mm_shuffle_epi32(s, 0x4E));
    s = _mm_add_epi32(s, _mm_shuffle_epi32(s, 0xB1));
    out[r] = _mm_cvtsi128_si32(s);
  }
}

__attribute__((target("avx512f,avx512bw"))) void DotsAvx512(const int16_t* q, const uint8_t* rows,
                                                            size_t n, int32_t* out) {
  __m512i qv[4];
  for (int k = 0; k < 4; ++k) qv[k] = _mm512_loadu_si512(q + 32 * k);
  for (size_t r = 0; r < n; ++r) {
    const uint8_t* row = rows + r * kDim;
    __m512i acc = _mm512_setzero_si512();
    for (int k = 0; k < 4; ++k) {
      const __m512i v =
          _mm512_cvtepu8_epi16(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(row + 32 * k)));
      acc = _mm512_add_epi32(acc, _mm512_madd_epi16(v, qv[k]));
    }
    // The two 256-bit halves summed, then as AVX2 (GCC 12 warns about
    // _mm512_reduce_add_epi32's own code).
    acc = _mm512_add_epi32(acc, _mm512_shuffle_i32x4(acc, acc, _MM_SHUFFLE(1, 0, 3, 2)));
    const __m256i half = _mm512_castsi512_si256(acc);
    __m128i s = _mm_add_epi32(_mm256_castsi256_si128(half), _mm256_extracti128_si256(half, 1));
    s = _mm_add_epi32(s, _mm_shuffle_epi32(s, 0x4E));
    s = _mm_add_epi32(s, _mm_shuffle_epi32(s, 0xB1));
    out[r] = _mm_cvtsi128_si32(s);
  }
}

// The `k` largest of `n` values (k <= n), as (value, index) sorted by value,
// the earlier index first among equals. Most values fail the comparison with
// the current k-th: the SIMD versions compare 16 or 8 at once and visit only
// the lanes above it; every version gives the same result.
struct TopK {
  float* dot;
  uint32_t* index;
  int k, size = 0;

  float Threshold() const { return size < k ? -INFINITY : dot[k - 1]; }
  void Offer(float d, uint32_t c) {
    if (size == k && !(d > dot[k - 1])) return;
    int at = size < k ? size++ : k - 1;
    for (; at > 0 && d > dot[at - 1]; --at) {
      dot[at] = dot[at - 1];
      index[at] = index[at - 1];
    }
    dot[at] = d;
    index[at] = c;
  }
};
using TopKKernel = void (*)(const float* d, int n, TopK* top);

void TopKPortable(const float* d, int n, TopK* top) {
  for (int c = 0; c < n; ++c) top->Offer(d[c], static_cast<uint32_t>(c));
}

__attribute__((target("avx2"))) void TopKAvx2(const float* d, int n, TopK* top) {
  int c = 0;
  for (; c + 8 <= n; c += 8) {
    int mask = _mm256_movemask_ps(
        _mm256_cmp_ps(_mm256_loadu_ps(d + c), _mm256_set1_ps(top->Threshold()), _CMP_GT_OQ));
    for (; mask; mask &= mask - 1) {
      const int lane = __builtin_ctz(mask);
      top->Offer(d[c + lane], static_cast<uint32_t>(c + lane));
    }
  }
  for (; c < n; ++c) top->Offer(d[c], static_cast<uint32_t>(c));
}

__attribute__((target("avx512f"))) void TopKAvx512(const float* d, int n, TopK* top) {
  int c = 0;
  for (; c + 16 <= n; c += 16) {
    unsigned mask =
        _mm512_cmp_ps_mask(_mm512_loadu_ps(d + c), _mm512_set1_ps(top->Threshold()), _CMP_GT_OQ);
    for (; mask; mask &= mask - 1) {
      const int lane = __builtin_ctz(mask);
      top->Offer(d[c + lane], static_cast<uint32_t>(c + lane));
    }
  }
  for (; c < n; ++c) top->Offer(d[c], static_cast<uint32_t>(c));
}

TopKKernel PickTopK() {
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512f")) return TopKAvx512;
  if (__builtin_cpu_supports("avx2")) return TopKAvx2;
  return TopKPortable;
}

const TopKKernel kTopK = PickTopK();

DotKernel PickKernel() {
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512bw")) return DotsAvx512;
  if (__builtin_cpu_supports("avx2")) return DotsAvx2;
  return DotsPortable;
}

const DotKernel kDots = PickKernel();

template <typename T>
void Append(std::string& out, const std::vector<T>& v) {
  out.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

template <typename T>
bool Take(std::string_view& in, size_t count, std::vector<T>* v) {
  if (count > in.size() / sizeof(T)) return false;
  v->resize(count);
  std::memcpy(v->data(), in.data(), count * sizeof(T));
  in.remove_prefix(count * sizeof(T));
  return true;
}

// The two best (dot, row) of a query; a tie goes to the smaller row.
struct Best2 {
  int32_t dot[2] = {-1, -1};
  int64_t id[2] = {-1, -1};
  void Offer(int32_t d, int64_t i) {
    if (d > dot[0] || (d == dot[0] && i < id[0])) {
      dot[1] = dot[0];
      id[1] = id[0];
      dot[0] = d;
      id[0] = i;
    } else if (d > dot[1] || (d == dot[1] && i < id[1])) {
      dot[1] = d;
      id[1] = i;
    }
  }
};

}  // namespace

struct IvfIndex::Coarse {
  faiss::IndexFlatIP flat{kDim};
};

IvfIndex::~IvfIndex() = default;

const char* IvfIndex::Kernel() {
  return kDots == DotsAvx512 ? "avx512bw" : kDots == DotsAvx2 ? "avx2" : "portable";
}

void IvfIndex::DotsWith(const std::string& kernel, const int16_t* query, const uint8_t* rows,
                        size_t n, int32_t* out) {
  if (kernel == "avx512bw" && __builtin_cpu_supports("avx512bw"))
    return DotsAvx512(query, rows, n, out);
  if (kernel == "avx2" && __builtin_cpu_supports("avx2")) return DotsAvx2(query, rows, n, out);
  if (kernel == "portable") return DotsPortable(query, rows, n, out);
  Fail("IVF kernel '{}' is not available on this CPU", kernel);
}

std::vector<uint32_t> IvfIndex::TopKWith(const std::string& kernel, const float* values, int n,
                                         int k) {
  TopKKernel run = nullptr;
  if (kernel == "avx512f" && __builtin_cpu_supports("avx512f")) run = TopKAvx512;
  if (kernel == "avx2" && __builtin_cpu_supports("avx2")) run = TopKAvx2;
  if (kernel == "portable") run = TopKPortable;
  if (!run) Fail("top-k kernel '{}' is not available on this CPU", kernel);
  if (k < 1 || k > n) Fail("top-k: need 1 <= k ({}) <= n ({})", k, n);
  std::vector<float> dot(k);
  std::vector<uint32_t> index(k);
  TopK top{dot.data(), index.data(), k};
  run(values, n, &top);
  return index;
}

void IvfIndex::MakeCoarse() {
  coarse_ = std::make_unique<Coarse>();
  coarse_->flat.add(nlist_, centroids_.data());
}

std::unique_ptr<IvfIndex> IvfIndex::Build(std::span<const uint8_t> d, int nlist, int threads) {
  if (d.size() % kDim != 0 || d.size() < 2 * kDim) {
    Fail("IVF index: at least two rows of {} bytes expected", kDim);
  }
  if (d.size() / kDim > UINT32_MAX) Fail("IVF index: more than 2^32 descriptors");
  const size_t n = d.size() / kDim;
  std::unique_ptr<IvfIndex> index(new IvfIndex());
  index->nlist_ = std::clamp<int>(nlist, 1, static_cast<int>(std::max<size_t>(1, n / 16)));
  const int cells = index->nlist_;
  OmpThreads team(std::max(1, threads));

  // k-means on an evenly spaced sample of 64 rows per cell.
  const size_t sample = std::min<size_t>(n, static_cast<size_t>(cells) * 64);
  std::vector<float> x(sample * kDim);
  for (size_t i = 0; i < sample; ++i) {
    const uint8_t* row = d.data() + (i * n / sample) * kDim;
    std::copy(row, row + kDim, x.begin() + i * kDim);
  }
  faiss::ClusteringParameters cp;
  cp.niter = 10;
  cp.seed = 1;
  cp.spherical = true;
  cp.max_points_per_centroid = 64;
  cp.min_points_per_centroid = 1;
  faiss::Clustering clustering(kDim, cells, cp);
  faiss::IndexFlatIP assigner(kDim);
  clustering.train(static_cast<faiss::Index::idx_t>(sample), x.data(), assigner);
  index->centroids_ = clustering.centroids;
  index->MakeCoarse();

  // Each row to its nearest centroid, then the rows stored cell by cell.
  std::vector<faiss::Index::idx_t> cell(n);
  constexpr size_t kChunk = 32768;
  std::vector<float> chunk, dist(kChunk);
  for (size_t start = 0; start < n; start += kChunk) {
    const size_t rows = std::min(kChunk, n - start);
    chunk.assign(d.begin() + start * kDim, d.begin() + (start + rows) * kDim);
    index->coarse_->flat.search(static_cast<faiss::Index::idx_t>(rows), chunk.data(), 1,
                                dist.data(), cell.data() + start);
  }
  index->offsets_.assign(cells + 1, 0);
  for (size_t i = 0; i < n; ++i) ++index->offsets_[cell[i] + 1];
  std::partial_sum(index->offsets_.begin(), index->offsets_.end(), index->offsets_.begin());
  std::vector<uint32_t> next(index->offsets_.begin(), index->offsets_.end() - 1);
  index->ids_.resize(n);
  index->rows_.resize(n * kDim);
  for (size_t i = 0; i < n; ++i) {
    const uint32_t slot = next[cell[i]]++;
    index->ids_[slot] = static_cast<uint32_t>(i);
    std::memcpy(index->rows_.data() + size_t(slot) * kDim, d.data() + i * kDim, kDim);
  }
  return index;
}

std::string IvfIndex::Serialize() const {
  std::string out = kMagic;
  const uint64_t header[2] = {static_cast<uint64_t>(nlist_), ids_.size()};
  out.append(reinterpret_cast<const char*>(header), sizeof(header));
  Append(out, centroids_);
  Append(out, offsets_);
  Append(out, ids_);
  Append(out, rows_);
  return out;
}

std::unique_ptr<IvfIndex> IvfIndex::Deserialize(std::string_view in, size_t rows) {
  const size_t magic = sizeof(kMagic) - 1;
  uint64_t header[2];
  if (in.size() < magic + sizeof(header) || in.substr(0, magic) != kMagic) return nullptr;
  in.remove_prefix(magic);
  std::memcpy(header, in.data(), sizeof(header));
  in.remove_prefix(sizeof(header));
  if (header[1] != rows || header[0] < 1 || header[0] > std::max<uint64_t>(1, rows)) return nullptr;
  std::unique_ptr<IvfIndex> index(new IvfIndex());
  index->nlist_ = static_cast<int>(header[0]);
  if (!Take(in, header[0] * kDim, &index->centroids_) ||
      !Take(in, header[0] + 1, &index->offsets_) || !Take(in, rows, &index->ids_) ||
      !Take(in, rows * kDim, &index->rows_) || !in.empty()) {
    return nullptr;
  }
  // Consistent: offsets rise from 0 to rows, ids are a permutation, centroids finite.
  if (index->offsets_.front() != 0 || index->offsets_.back() != rows ||
      !std::is_sorted(index->offsets_.begin(), index->offsets_.end())) {
    return nullptr;
  }
  std::vector<bool> seen(rows, false);
  for (const uint32_t id : index->ids_) {
    if (id >= rows || seen[id]) return nullptr;
    seen[id] = true;
  }
  for (const float c : index->centroids_) {
    if (!std::isfinite(c)) return nullptr;
  }
  index->MakeCoarse();
  return index;
}

void IvfIndex::Search(std::span<const uint8_t> queries, int nprobe, int64_t* ids) const {
  const size_t nq = queries.size() / kDim;
  if (nq == 0) return;
  nprobe = std::clamp(nprobe, 1, nlist_);
  // Coarse: the nprobe nearest centroids of each query, as a BLAS product of
  // a block of queries with the centroids, then a top-k selection per row
  // (TopK). FAISS's flat index did the same through a generic heap: a third of
  // the search on a 13 000-line map.
  std::vector<uint32_t> cells(nq * nprobe);
  std::vector<uint32_t> per_cell(nlist_ + 1, 0);
  {
    OmpThreads one(1);  // OpenBLAS (OpenMP build) on this thread only
    constexpr int kBlock = 256;
    std::vector<float> q(size_t(kBlock) * kDim), dots(size_t(kBlock) * nlist_);
    std::vector<float> top_dot(nprobe);
    for (size_t first = 0; first < nq; first += kBlock) {
      int rows = static_cast<int>(std::min<size_t>(kBlock, nq - first));
      std::copy_n(queries.data() + first * kDim, size_t(rows) * kDim, q.data());
      int nlist = nlist_, dim = kDim;
      const float one = 1, zero = 0;
      sgemm_("T", "N", &nlist, &rows, &dim, &one, centroids_.data(), &dim, q.data(), &dim, &zero,
             dots.data(), &nlist);
      for (int r = 0; r < rows; ++r) {
        uint32_t* top = cells.data() + (first + r) * nprobe;
        TopK selection{top_dot.data(), top, nprobe};
        kTopK(dots.data() + size_t(r) * nlist_, nlist_, &selection);
        for (int k = 0; k < nprobe; ++k) ++per_cell[top[k] + 1];
      }
    }
  }
  // (cell, query) pairs in cell order, queries ascending within a cell (a
  // counting sort): each cell's rows are read once per batch.
  for (int c = 0; c < nlist_; ++c) per_cell[c + 1] += per_cell[c];
  std::vector<std::pair<uint32_t, uint32_t>> visits(nq * nprobe);
  {
    std::vector<uint32_t> next(per_cell.begin(), per_cell.end() - 1);
    for (size_t i = 0; i < nq; ++i) {
      for (int p = 0; p < nprobe; ++p) {
        const uint32_t c = cells[i * nprobe + p];
        visits[next[c]++] = {c, static_cast<uint32_t>(i)};
      }
    }
  }
  std::vector<int16_t> q16(queries.begin(), queries.end());
  std::vector<Best2> best(nq);
  std::vector<int32_t> dots;
  for (const auto& [c, i] : visits) {
    const uint32_t begin = offsets_[c], count = offsets_[c + 1] - begin;
    dots.resize(count);
    kDots(q16.data() + size_t(i) * kDim, rows_.data() + size_t(begin) * kDim, count, dots.data());
    for (uint32_t r = 0; r < count; ++r) best[i].Offer(dots[r], ids_[begin + r]);
  }
  for (size_t i = 0; i < nq; ++i) {
    ids[2 * i] = best[i].id[0];
    ids[2 * i + 1] = best[i].id[1];
  }
}

}  // namespace linecloud
