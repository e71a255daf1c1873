#include "linecloud/features/descriptor_index.h"

#include <flann/flann.hpp>
#include <sodium.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>

#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

constexpr int kDim = 128;
constexpr char kMagic[] = "linecloud-flann-kdtree-v1";

std::array<unsigned char, 32> DescriptorsHash(std::span<const uint8_t> d) {
  std::array<unsigned char, 32> h;
  crypto_generichash(h.data(), h.size(), d.data(), d.size(), nullptr, 0);
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
  std::unique_ptr<flann::Index<flann::L2<float>>> index;
  DescriptorIndexOptions options;

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
                                 const DescriptorIndexOptions& options)
    : impl_(std::make_unique<Impl>()) {
  options.Check();
  if (descriptors.size() % kDim != 0) Fail("descriptor index: rows of {} bytes expected", kDim);
  impl_->descriptors = descriptors;
  impl_->options = options;
  impl_->data.resize(descriptors.size());
  for (size_t i = 0; i < descriptors.size(); i += kDim)
    ToFloat(descriptors.data() + i, &impl_->data[i]);
  if (impl_->data.empty()) return;
  // FLANN's randomised kd-trees draw their split dimensions with rand():
  // seeded, so that an index (and its matches) is the same on every run.
  std::srand(1);
  impl_->index = std::make_unique<flann::Index<flann::L2<float>>>(
      impl_->Matrix(), flann::KDTreeIndexParams(options.trees));
  impl_->index->buildIndex();
}

DescriptorIndex::~DescriptorIndex() = default;

size_t DescriptorIndex::size() const { return impl_->descriptors.size() / kDim; }

void DescriptorIndex::Save(const std::string& path) const {
  if (!impl_->index) Fail("{}: an empty index has nothing to save", path);
  // FLANN writes to a path: write it beside, then prepend our header.
  const std::string raw = path + ".flann.tmp";
  impl_->index->save(raw);
  std::string body = ReadFileToString(raw);
  std::remove(raw.c_str());
  const auto hash = DescriptorsHash(impl_->descriptors);
  WriteFileAtomically(path, [&](std::ostream& os) {
    os << kMagic << '\n';
    os.write(reinterpret_cast<const char*>(hash.data()), hash.size());
    os << body;
  });
}

std::unique_ptr<DescriptorIndex> DescriptorIndex::Load(const std::string& path,
                                                       std::span<const uint8_t> descriptors,
                                                       const DescriptorIndexOptions& options) {
  if (!FileExists(path) || descriptors.empty()) return nullptr;
  std::string data;
  try {
    data = ReadFileToString(path);
  } catch (const Error&) {
    return nullptr;
  }
  const std::string magic = std::string(kMagic) + "\n";
  if (data.compare(0, magic.size(), magic) != 0 || data.size() < magic.size() + 32) return nullptr;
  const auto hash = DescriptorsHash(descriptors);
  if (std::memcmp(data.data() + magic.size(), hash.data(), 32) != 0) return nullptr;  // stale
  const std::string raw = path + ".flann.tmp";
  WriteFileAtomically(raw, [&](std::ostream& os) { os << data.substr(magic.size() + 32); });
  std::unique_ptr<DescriptorIndex> index(new DescriptorIndex());
  index->impl_ = std::make_unique<Impl>();
  Impl& impl = *index->impl_;
  impl.descriptors = descriptors;
  impl.options = options;
  impl.data.resize(descriptors.size());
  for (size_t i = 0; i < descriptors.size(); i += kDim)
    ToFloat(descriptors.data() + i, &impl.data[i]);
  try {
    impl.index = std::make_unique<flann::Index<flann::L2<float>>>(impl.Matrix(),
                                                                  flann::SavedIndexParams(raw));
  } catch (const std::exception&) {
    std::remove(raw.c_str());
    return nullptr;
  }
  std::remove(raw.c_str());
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
