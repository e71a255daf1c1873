#include "linecloud/features/descriptor_index.h"

// Every header FLANN's kd-tree includes from the standard library, first, so
// that the two macros below reach FLANN's code only.
#include <sodium.h>
#include <stdarg.h>

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <random>
#include <thread>
#include <vector>

// FLANN's randomised kd-trees draw split dimensions with std::rand() (whose
// seed is the host program's) and shuffle with std::random_device (a new
// index every run). Our own flann/util/random.h stands in for FLANN's (same
// names, a thread-local generator reseeded for every build), and its shuffle
// gets a default-seeded engine: the same index from the same descriptors, in
// any thread, without touching the program's rand().
#define FLANN_RANDOM_H
namespace flann {
inline std::mt19937& SeededEngine() {
  thread_local std::mt19937 engine;
  return engine;
}
inline void seed_random(unsigned int seed) { SeededEngine().seed(seed); }
inline double rand_double(double high = 1.0, double low = 0) {
  return std::uniform_real_distribution<double>(low, high)(SeededEngine());
}
inline int rand_int(int high = RAND_MAX, int low = 0) {
  return low + static_cast<int>(SeededEngine()() % static_cast<unsigned>(std::max(1, high - low)));
}
}  // namespace flann
#define random_device minstd_rand
#include <flann/algorithms/dist.h>
#include <flann/algorithms/kdtree_index.h>
#undef random_device

#include <faiss/IndexFlat.h>
#include <faiss/IndexHNSW.h>
#include <faiss/IndexScalarQuantizer.h>
#include <faiss/impl/io.h>
#include <faiss/index_io.h>
#include <hnswlib/hnswlib.h>

#include "linecloud/features/ivf_index.h"
#include "linecloud/features/omp_threads.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

constexpr int kDim = 128;
constexpr char kMagic[] = "linecloud-descriptor-index-v3\n";
constexpr size_t kHashBytes = 32;
constexpr unsigned kBuildSeed = 1;
// A cache larger than this per descriptor is no cache of ours (FAISS's IVF
// keeps the 128 bytes and an 8-byte id; FLANN's trees ~ trees x 2 nodes x 24
// bytes per point; HNSW ~ 2 M links of 4 bytes and the data as floats).
constexpr size_t kMaxCacheBytesPerDescriptor = 1024;

using Hash = std::array<unsigned char, kHashBytes>;
using KdTrees = flann::KDTreeIndex<flann::L2<float>>;

Hash DescriptorsHash(std::span<const uint8_t> d) {
  Hash h;
  crypto_generichash(h.data(), h.size(), d.data(), d.size(), nullptr, 0);
  return h;
}

Hash Mac(std::string_view data, std::span<const uint8_t, 32> key) {
  Hash h;
  crypto_generichash(h.data(), h.size(), reinterpret_cast<const unsigned char*>(data.data()),
                     data.size(), key.data(), key.size());
  return h;
}

std::vector<float> ToFloat(std::span<const uint8_t> bytes) {
  return std::vector<float>(bytes.begin(), bytes.end());
}

float Dot(const uint8_t* a, const uint8_t* b) {
  int s = 0;
  for (int i = 0; i < kDim; ++i) s += int(a[i]) * int(b[i]);
  return static_cast<float>(s);
}

// One kind of index: the two nearest neighbours of float queries.
class Backend {
 public:
  virtual ~Backend() = default;
  // ids: 2 per query, -1 where there is none. `queries` are the bytes,
  // `floats` the same as floats. Called from one thread.
  virtual void Search(const uint8_t* queries, const float* floats, size_t n,
                      int64_t* ids) const = 0;
  virtual std::string Serialize() const = 0;
};

class FlannBackend : public Backend {
 public:
  FlannBackend(std::span<const uint8_t> d, const DescriptorIndexOptions& o)
      : data_(ToFloat(d)), options_(o) {
    trees_ = std::make_unique<KdTrees>(Matrix(), flann::KDTreeIndexParams(o.trees));
  }
  void Build() {
    flann::seed_random(kBuildSeed);
    trees_->buildIndex();
  }
  bool Load(const char* data, size_t size) {
    FILE* stream = ::fmemopen(const_cast<char*>(data), size, "rb");
    if (stream == nullptr) return false;
    bool ok = true;
    try {
      trees_->loadIndex(stream);
    } catch (const std::exception&) {
      ok = false;
    }
    std::fclose(stream);
    return ok && trees_->size() == data_.size() / kDim;
  }
  void Search(const uint8_t*, const float* queries, size_t n, int64_t* ids) const override {
    std::vector<int> indices(2 * n, -1);
    std::vector<float> distances(2 * n);
    flann::Matrix<int> ind(indices.data(), n, 2);
    flann::Matrix<float> dist(distances.data(), n, 2);
    flann::SearchParams params(options_.checks);
    params.cores = 1;
    trees_->knnSearch(flann::Matrix<float>(const_cast<float*>(queries), n, kDim), ind, dist, 2,
                      params);
    for (size_t i = 0; i < 2 * n; ++i) ids[i] = indices[i];
  }
  std::string Serialize() const override {
    char* buffer = nullptr;  // FLANN writes to a FILE*: an in-memory one
    size_t size = 0;
    FILE* stream = ::open_memstream(&buffer, &size);
    if (stream == nullptr) Fail("cannot serialise the index");
    try {
      trees_->saveIndex(stream);
    } catch (const std::exception& e) {
      std::fclose(stream);
      std::free(buffer);
      Fail("cannot serialise the index ({})", e.what());
    }
    std::fclose(stream);
    std::string out(buffer, size);
    std::free(buffer);
    return out;
  }

 private:
  flann::Matrix<float> Matrix() {
    return flann::Matrix<float>(data_.data(), data_.size() / kDim, kDim);
  }
  std::vector<float> data_;
  DescriptorIndexOptions options_;
  std::unique_ptr<KdTrees> trees_;
};

// FAISS's IVF and HNSW share searching and serialisation.
class FaissBackend : public Backend {
 public:
  explicit FaissBackend(std::unique_ptr<faiss::Index> index) : index_(std::move(index)) {}
  void Search(const uint8_t*, const float* queries, size_t n, int64_t* ids) const override {
    std::vector<float> distances(2 * n);
    static_assert(sizeof(faiss::Index::idx_t) == sizeof(int64_t));
    index_->search(static_cast<faiss::Index::idx_t>(n), queries, 2, distances.data(),
                   reinterpret_cast<faiss::Index::idx_t*>(ids));
  }
  std::string Serialize() const override {
    faiss::VectorIOWriter writer;
    faiss::write_index(index_.get(), &writer);
    return std::string(writer.data.begin(), writer.data.end());
  }
  const faiss::Index& index() const { return *index_; }

 private:
  std::unique_ptr<faiss::Index> index_;
};

int CellCount(size_t n, const DescriptorIndexOptions& o) {
  if (o.nlist > 0) return static_cast<int>(std::min<size_t>(o.nlist, std::max<size_t>(1, n / 32)));
  const double cells = 4 * std::sqrt(static_cast<double>(n));
  return static_cast<int>(std::clamp<double>(std::round(cells), 1, std::max<size_t>(1, n / 32)));
}

std::unique_ptr<Backend> BuildFaissIvf(std::span<const uint8_t> d,
                                       const DescriptorIndexOptions& o) {
  const size_t n = d.size() / kDim;
  const int cells = CellCount(n, o);
  auto quantizer = std::make_unique<faiss::IndexFlatIP>(kDim);
  auto ivf = std::make_unique<faiss::IndexIVFScalarQuantizer>(
      quantizer.get(), kDim, cells, faiss::ScalarQuantizer::QT_8bit_direct,
      faiss::METRIC_INNER_PRODUCT, /*encode_residual=*/false);
  ivf->own_fields = true;
  quantizer.release();
  ivf->cp.seed = static_cast<int>(kBuildSeed);
  ivf->cp.niter = 10;
  ivf->cp.max_points_per_centroid = 64;
  ivf->nprobe = std::min(o.nprobe, cells);
  OmpThreads threads(o.threads);
  // k-means on an evenly spaced sample (FAISS would otherwise subsample from
  // all n float rows, which would have to exist first).
  const size_t sample = std::min<size_t>(n, static_cast<size_t>(cells) * 64);
  std::vector<float> training(sample * kDim);
  for (size_t i = 0; i < sample; ++i) {
    const uint8_t* row = d.data() + (i * n / sample) * kDim;
    std::copy(row, row + kDim, training.begin() + i * kDim);
  }
  ivf->train(static_cast<faiss::Index::idx_t>(sample), training.data());
  constexpr size_t kChunk = 65536;
  for (size_t start = 0; start < n; start += kChunk) {
    const size_t rows = std::min(kChunk, n - start);
    const std::vector<float> chunk = ToFloat(d.subspan(start * kDim, rows * kDim));
    ivf->add(static_cast<faiss::Index::idx_t>(rows), chunk.data());
  }
  return std::make_unique<FaissBackend>(std::move(ivf));
}

std::unique_ptr<Backend> BuildFaissHnsw(std::span<const uint8_t> d,
                                        const DescriptorIndexOptions& o) {
  auto hnsw = std::make_unique<faiss::IndexHNSWFlat>(kDim, o.hnsw_m, faiss::METRIC_INNER_PRODUCT);
  hnsw->hnsw.efConstruction = o.ef_construction;
  hnsw->hnsw.efSearch = o.ef_search;
  // FAISS inserts in parallel, which makes the graph depend on timing: one
  // thread builds the same graph every time.
  OmpThreads threads(1);
  const std::vector<float> data = ToFloat(d);
  hnsw->add(static_cast<faiss::Index::idx_t>(d.size() / kDim), data.data());
  return std::make_unique<FaissBackend>(std::move(hnsw));
}

class HnswlibBackend : public Backend {
 public:
  HnswlibBackend(std::span<const uint8_t> d, const DescriptorIndexOptions& o) : space_(kDim) {
    const size_t n = d.size() / kDim;
    graph_ = std::make_unique<hnswlib::HierarchicalNSW<float>>(&space_, n, o.hnsw_m,
                                                               o.ef_construction, kBuildSeed);
    graph_->setEf(o.ef_search);
    std::array<float, kDim> row;
    for (size_t i = 0; i < n; ++i) {
      std::copy(d.data() + i * kDim, d.data() + (i + 1) * kDim, row.begin());
      graph_->addPoint(row.data(), i);
    }
  }
  void Search(const uint8_t*, const float* queries, size_t n, int64_t* ids) const override {
    for (size_t i = 0; i < n; ++i) {
      auto found = graph_->searchKnn(queries + i * kDim, 2);  // farthest on top
      ids[2 * i] = ids[2 * i + 1] = -1;
      for (int slot = static_cast<int>(found.size()) - 1; slot >= 0; --slot) {
        ids[2 * i + slot] = static_cast<int64_t>(found.top().second);
        found.pop();
      }
    }
  }
  std::string Serialize() const override {
    Fail("hnswlib indexes are not cached (hnswlib 0.6 writes to a named file only)");
  }

 private:
  hnswlib::InnerProductSpace space_;
  std::unique_ptr<hnswlib::HierarchicalNSW<float>> graph_;
};

class IvfBackend : public Backend {
 public:
  IvfBackend(std::unique_ptr<IvfIndex> index, int nprobe)
      : index_(std::move(index)), nprobe_(nprobe) {}
  void Search(const uint8_t* queries, const float*, size_t n, int64_t* ids) const override {
    index_->Search(std::span<const uint8_t>(queries, n * kDim), nprobe_, ids);
  }
  std::string Serialize() const override { return index_->Serialize(); }

 private:
  std::unique_ptr<IvfIndex> index_;
  int nprobe_;
};

std::unique_ptr<Backend> BuildBackend(std::span<const uint8_t> d, const DescriptorIndexOptions& o) {
  switch (o.kind) {
    case DescriptorIndexKind::kIvf:
      return std::make_unique<IvfBackend>(
          IvfIndex::Build(d, CellCount(d.size() / kDim, o), o.threads), o.nprobe);
    case DescriptorIndexKind::kFaissIvf:
      return BuildFaissIvf(d, o);
    case DescriptorIndexKind::kFaissHnsw:
      return BuildFaissHnsw(d, o);
    case DescriptorIndexKind::kHnswlib:
      return std::make_unique<HnswlibBackend>(d, o);
    case DescriptorIndexKind::kFlann: {
      auto flann = std::make_unique<FlannBackend>(d, o);
      flann->Build();
      return flann;
    }
  }
  Fail("descriptor index: unknown kind");
}

// A FAISS index read back from a cache: the kind and size it must have.
std::unique_ptr<Backend> LoadFaiss(const char* data, size_t size, size_t n,
                                   const DescriptorIndexOptions& o) {
  faiss::VectorIOReader reader;
  reader.data.assign(data, data + size);
  std::unique_ptr<faiss::Index> index;
  try {
    index.reset(faiss::read_index(&reader));
  } catch (const std::exception&) {
    return nullptr;
  }
  if (!index || index->d != kDim || static_cast<size_t>(index->ntotal) != n) return nullptr;
  if (auto* ivf = dynamic_cast<faiss::IndexIVFScalarQuantizer*>(index.get())) {
    if (o.kind != DescriptorIndexKind::kFaissIvf) return nullptr;
    ivf->nprobe = std::min<size_t>(o.nprobe, ivf->nlist);
  } else if (auto* hnsw = dynamic_cast<faiss::IndexHNSWFlat*>(index.get())) {
    if (o.kind != DescriptorIndexKind::kFaissHnsw) return nullptr;
    hnsw->hnsw.efSearch = o.ef_search;
  } else {
    return nullptr;
  }
  return std::make_unique<FaissBackend>(std::move(index));
}

}  // namespace

DescriptorIndexKind ParseDescriptorIndexKind(const std::string& name, const std::string& option) {
  for (const DescriptorIndexKind k :
       {DescriptorIndexKind::kIvf, DescriptorIndexKind::kFaissIvf, DescriptorIndexKind::kFaissHnsw,
        DescriptorIndexKind::kHnswlib, DescriptorIndexKind::kFlann}) {
    if (name == DescriptorIndexKindName(k)) return k;
  }
  Fail("{}: unknown index '{}' (ivf, faiss-ivf, faiss-hnsw, hnswlib or flann)", option, name);
}

const char* DescriptorIndexKindName(DescriptorIndexKind kind) {
  switch (kind) {
    case DescriptorIndexKind::kIvf:
      return "ivf";
    case DescriptorIndexKind::kFaissIvf:
      return "faiss-ivf";
    case DescriptorIndexKind::kFaissHnsw:
      return "faiss-hnsw";
    case DescriptorIndexKind::kHnswlib:
      return "hnswlib";
    case DescriptorIndexKind::kFlann:
      return "flann";
  }
  return "?";
}

struct DescriptorIndex::Impl {
  std::span<const uint8_t> descriptors;
  DescriptorIndexOptions options;
  std::unique_ptr<Backend> backend;
};

void DescriptorIndexOptions::Check() const {
  if (trees < 1 || checks < 2 || threads < 1) {
    Fail("descriptor index: trees {}, checks {} and threads {} must be at least 1, 2 and 1", trees,
         checks, threads);
  }
  if (nlist < 0 || nprobe < 1) {
    Fail("descriptor index: nlist {} must be at least 0 and nprobe {} at least 1", nlist, nprobe);
  }
  if (hnsw_m < 2 || hnsw_m > 256 || ef_construction < 2 || ef_search < 2) {
    Fail("descriptor index: HNSW M {} (2..256), ef_construction {} and ef_search {} (>= 2)", hnsw_m,
         ef_construction, ef_search);
  }
}

DescriptorIndex::DescriptorIndex(std::span<const uint8_t> descriptors,
                                 const DescriptorIndexOptions& options) {
  options.Check();
  if (descriptors.size() % kDim != 0) Fail("descriptor index: rows of {} bytes expected", kDim);
  impl_ = std::make_unique<Impl>();
  impl_->descriptors = descriptors;
  impl_->options = options;
  if (descriptors.size() / kDim >= 2) impl_->backend = BuildBackend(descriptors, options);
}

DescriptorIndex::~DescriptorIndex() = default;

size_t DescriptorIndex::size() const { return impl_->descriptors.size() / kDim; }

DescriptorIndexKind DescriptorIndex::kind() const { return impl_->options.kind; }

void DescriptorIndex::Save(const std::string& path, std::span<const uint8_t, 32> mac_key) const {
  if (!impl_->backend) Fail("{}: an empty index has nothing to save", path);
  std::string body = kMagic;
  body += DescriptorIndexKindName(impl_->options.kind);
  body += '\n';
  const Hash hash = DescriptorsHash(impl_->descriptors);
  body.append(reinterpret_cast<const char*>(hash.data()), hash.size());
  try {
    body += impl_->backend->Serialize();
  } catch (const Error& e) {
    Fail("{}: {}", path, e.what());
  } catch (const std::exception& e) {
    Fail("{}: cannot serialise the index ({})", path, e.what());
  }
  const Hash mac = Mac(body, mac_key);
  body.append(reinterpret_cast<const char*>(mac.data()), mac.size());
  WriteFileAtomically(path, [&](std::ostream& os) { os << body; });
}

std::unique_ptr<DescriptorIndex> DescriptorIndex::Load(const std::string& path,
                                                       std::span<const uint8_t> descriptors,
                                                       const DescriptorIndexOptions& options,
                                                       std::span<const uint8_t, 32> mac_key) {
  options.Check();
  if (!FileExists(path) || descriptors.size() < 2 * kDim || descriptors.size() % kDim != 0) {
    return nullptr;
  }
  const size_t n = descriptors.size() / kDim;
  std::string data;
  try {
    const size_t limit = n * kMaxCacheBytesPerDescriptor + (1 << 20);
    data = ReadFilePrefix(path, limit + 1);
    if (data.size() > limit) return nullptr;
  } catch (const Error&) {
    return nullptr;
  }
  const std::string header = std::string(kMagic) + DescriptorIndexKindName(options.kind) + "\n";
  if (data.size() < header.size() + 2 * kHashBytes || data.compare(0, header.size(), header) != 0) {
    return nullptr;  // not ours, or an index of another kind
  }
  // Only an index this user's own key authenticated is parsed: FLANN's and
  // FAISS's readers trust their input (a crafted tree crashes the search).
  const std::string_view signed_part(data.data(), data.size() - kHashBytes);
  const Hash mac = Mac(signed_part, mac_key);
  if (sodium_memcmp(mac.data(), data.data() + signed_part.size(), kHashBytes) != 0) return nullptr;
  const Hash hash = DescriptorsHash(descriptors);
  if (std::memcmp(data.data() + header.size(), hash.data(), kHashBytes) != 0) return nullptr;
  const size_t start = header.size() + kHashBytes;
  const char* payload = data.data() + start;
  const size_t payload_size = signed_part.size() - start;

  std::unique_ptr<DescriptorIndex> index(new DescriptorIndex());
  index->impl_ = std::make_unique<Impl>();
  index->impl_->descriptors = descriptors;
  index->impl_->options = options;
  switch (options.kind) {
    case DescriptorIndexKind::kIvf: {
      auto ivf = IvfIndex::Deserialize(std::string_view(payload, payload_size), n);
      if (ivf) index->impl_->backend = std::make_unique<IvfBackend>(std::move(ivf), options.nprobe);
      break;
    }
    case DescriptorIndexKind::kFlann: {
      auto flann = std::make_unique<FlannBackend>(descriptors, options);
      if (!flann->Load(payload, payload_size)) return nullptr;
      index->impl_->backend = std::move(flann);
      break;
    }
    case DescriptorIndexKind::kFaissIvf:
    case DescriptorIndexKind::kFaissHnsw:
      index->impl_->backend = LoadFaiss(payload, payload_size, n, options);
      break;
    case DescriptorIndexKind::kHnswlib:
      return nullptr;
  }
  if (!index->impl_->backend) return nullptr;
  return index;
}

std::vector<DescriptorMatch> DescriptorIndex::Match(std::span<const uint8_t> query,
                                                    const DescriptorMatchOptions& options,
                                                    int threads) const {
  options.Check();
  if (options.cross_check) Fail("matching: the approximate index has no mutual check");
  if (query.size() % kDim != 0) Fail("matching: query rows of {} bytes expected", kDim);
  if (threads <= 0) threads = impl_->options.threads;
  std::vector<DescriptorMatch> matches;
  if (!impl_->backend || query.empty()) return matches;
  const size_t nq = query.size() / kDim;
  const std::vector<float> q = ToFloat(query);
  std::vector<int64_t> ids(2 * nq, -1);
  // Contiguous blocks of queries, one per thread; each query's neighbours do
  // not depend on the others, so neither do the matches on the thread count.
  const size_t workers = std::clamp<size_t>(threads, 1, std::max<size_t>(1, nq / 64));
  auto search = [&](size_t w) {
    const size_t begin = nq * w / workers, end = nq * (w + 1) / workers;
    OmpThreads one(1);
    impl_->backend->Search(query.data() + begin * kDim, q.data() + begin * kDim, end - begin,
                           ids.data() + 2 * begin);
  };
  if (workers == 1) {
    search(0);
  } else {
    std::vector<std::thread> pool;
    for (size_t w = 1; w < workers; ++w) pool.emplace_back(search, w);
    search(0);
    for (std::thread& t : pool) t.join();
  }
  const uint8_t* d = impl_->descriptors.data();
  const int64_t n = static_cast<int64_t>(size());
  for (size_t i = 0; i < nq; ++i) {
    const int64_t best = ids[2 * i], second = ids[2 * i + 1];
    if (best < 0 || second < 0 || best >= n || second >= n) continue;
    const uint8_t* qi = query.data() + i * kDim;
    if (const auto m = TestMatch(static_cast<int>(i), static_cast<int>(best),
                                 Dot(qi, d + best * kDim), Dot(qi, d + second * kDim), options)) {
      matches.push_back(*m);
    }
  }
  return matches;
}

}  // namespace linecloud
