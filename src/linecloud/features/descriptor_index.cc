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

#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

constexpr int kDim = 128;
constexpr char kMagic[] = "linecloud-flann-kdtree-v2\n";
constexpr size_t kHashBytes = 32;
constexpr unsigned kBuildSeed = 1;
// A cache larger than this per descriptor is no cache of ours (FLANN's trees
// take ~ trees x 2 nodes x 24 bytes per point, LZ4-compressed).
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

void ToFloat(const uint8_t* in, float* out) {
  for (int i = 0; i < kDim; ++i) out[i] = in[i];
}

float Dot(const uint8_t* a, const uint8_t* b) {
  int s = 0;
  for (int i = 0; i < kDim; ++i) s += int(a[i]) * int(b[i]);
  return static_cast<float>(s);
}

}  // namespace

struct DescriptorIndex::Impl {
  std::span<const uint8_t> descriptors;
  std::vector<float> data;  // the descriptors as float rows (FLANN indexes these)
  std::unique_ptr<KdTrees> index;
  DescriptorIndexOptions options;

  // Keeps `descriptors` by reference and their float copy, for a built or a
  // loaded index.
  Impl(std::span<const uint8_t> d, const DescriptorIndexOptions& o)
      : descriptors(d), data(d.size()), options(o) {
    for (size_t i = 0; i < d.size(); i += kDim) ToFloat(d.data() + i, &data[i]);
  }

  flann::Matrix<float> Matrix() {
    return flann::Matrix<float>(data.data(), data.size() / kDim, kDim);
  }
};

void DescriptorIndexOptions::Check() const {
  if (trees < 1 || checks < 2 || threads < 1) {
    Fail("descriptor index: trees {}, checks {} and threads {} must be at least 1, 2 and 1", trees,
         checks, threads);
  }
}

DescriptorIndex::DescriptorIndex(std::span<const uint8_t> descriptors,
                                 const DescriptorIndexOptions& options) {
  options.Check();
  if (descriptors.size() % kDim != 0) Fail("descriptor index: rows of {} bytes expected", kDim);
  impl_ = std::make_unique<Impl>(descriptors, options);
  if (impl_->data.empty()) return;
  flann::seed_random(kBuildSeed);
  impl_->index =
      std::make_unique<KdTrees>(impl_->Matrix(), flann::KDTreeIndexParams(options.trees));
  impl_->index->buildIndex();
}

DescriptorIndex::~DescriptorIndex() = default;

size_t DescriptorIndex::size() const { return impl_->descriptors.size() / kDim; }

void DescriptorIndex::Save(const std::string& path, std::span<const uint8_t, 32> mac_key) const {
  if (!impl_->index) Fail("{}: an empty index has nothing to save", path);
  // FLANN serialises to a FILE*: an in-memory one (no temporary file).
  char* buffer = nullptr;
  size_t size = 0;
  FILE* stream = ::open_memstream(&buffer, &size);
  if (stream == nullptr) Fail("{}: cannot serialise the index", path);
  try {
    impl_->index->saveIndex(stream);
  } catch (const std::exception& e) {
    std::fclose(stream);
    std::free(buffer);
    Fail("{}: cannot serialise the index ({})", path, e.what());
  }
  std::fclose(stream);
  std::string body = kMagic;
  const Hash hash = DescriptorsHash(impl_->descriptors);
  body.append(reinterpret_cast<const char*>(hash.data()), hash.size());
  body.append(buffer, size);
  std::free(buffer);
  const Hash mac = Mac(body, mac_key);
  body.append(reinterpret_cast<const char*>(mac.data()), mac.size());
  WriteFileAtomically(path, [&](std::ostream& os) { os << body; });
}

std::unique_ptr<DescriptorIndex> DescriptorIndex::Load(const std::string& path,
                                                       std::span<const uint8_t> descriptors,
                                                       const DescriptorIndexOptions& options,
                                                       std::span<const uint8_t, 32> mac_key) {
  if (!FileExists(path) || descriptors.empty() || descriptors.size() % kDim != 0) return nullptr;
  std::string data;
  try {
    const size_t limit = descriptors.size() / kDim * kMaxCacheBytesPerDescriptor + (1 << 20);
    data = ReadFilePrefix(path, limit + 1);
    if (data.size() > limit) return nullptr;
  } catch (const Error&) {
    return nullptr;
  }
  const size_t magic = sizeof(kMagic) - 1;
  if (data.size() < magic + 2 * kHashBytes || data.compare(0, magic, kMagic) != 0) return nullptr;
  // Only an index this user's own key authenticated is parsed: FLANN's reader
  // trusts its input (a crafted tree crashes the search).
  const std::string_view signed_part(data.data(), data.size() - kHashBytes);
  const Hash mac = Mac(signed_part, mac_key);
  if (sodium_memcmp(mac.data(), data.data() + signed_part.size(), kHashBytes) != 0) return nullptr;
  const Hash hash = DescriptorsHash(descriptors);
  if (std::memcmp(data.data() + magic, hash.data(), kHashBytes) != 0) return nullptr;  // stale
  std::unique_ptr<DescriptorIndex> index(new DescriptorIndex());
  index->impl_ = std::make_unique<Impl>(descriptors, options);
  Impl& impl = *index->impl_;
  const size_t start = magic + kHashBytes;
  FILE* stream = ::fmemopen(data.data() + start, signed_part.size() - start, "rb");
  if (stream == nullptr) return nullptr;
  try {
    impl.index = std::make_unique<KdTrees>(impl.Matrix(), flann::KDTreeIndexParams(options.trees));
    impl.index->loadIndex(stream);
  } catch (const std::exception&) {
    std::fclose(stream);
    return nullptr;
  }
  std::fclose(stream);
  if (impl.index->size() != descriptors.size() / kDim) return nullptr;
  return index;
}

std::vector<DescriptorMatch> DescriptorIndex::Match(std::span<const uint8_t> query,
                                                    const DescriptorMatchOptions& options) const {
  options.Check();
  if (options.cross_check) Fail("matching: the approximate index has no mutual check");
  if (query.size() % kDim != 0) Fail("matching: query rows of {} bytes expected", kDim);
  std::vector<DescriptorMatch> matches;
  if (size() < 2 || query.empty()) return matches;
  const size_t nq = query.size() / kDim;
  std::vector<float> q(query.size());
  for (size_t i = 0; i < query.size(); i += kDim) ToFloat(query.data() + i, &q[i]);
  std::vector<int> indices(2 * nq, -1);
  std::vector<float> distances(2 * nq);
  flann::Matrix<int> ind(indices.data(), nq, 2);
  flann::Matrix<float> dist(distances.data(), nq, 2);
  flann::SearchParams params(impl_->options.checks);
  params.cores = 1;
  impl_->index->knnSearch(flann::Matrix<float>(q.data(), nq, kDim), ind, dist, 2, params);
  for (size_t i = 0; i < nq; ++i) {
    const int best = indices[2 * i], second = indices[2 * i + 1];
    if (best < 0 || second < 0) continue;
    const uint8_t* qi = query.data() + i * kDim;
    const uint8_t* d = impl_->descriptors.data();
    if (const auto m = TestMatch(static_cast<int>(i), best, Dot(qi, d + size_t(best) * kDim),
                                 Dot(qi, d + size_t(second) * kDim), options)) {
      matches.push_back(*m);
    }
  }
  return matches;
}

}  // namespace linecloud
