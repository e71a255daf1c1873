#include "linecloud/features/descriptor_index.h"

// hnswlib 0.6.2's SSE path prefetches one entry past the end of a neighbour
// list (the value only feeds _mm_prefetch; harmless, but AddressSanitizer
// reports the read). Sanitizer builds take its portable path instead.
#if defined(__SANITIZE_ADDRESS__)
#define NO_MANUAL_VECTORIZATION
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define NO_MANUAL_VECTORIZATION
#endif
#endif
#include <hnswlib/hnswlib.h>
#include <sodium.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <thread>

#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

constexpr int kDim = 128;
constexpr char kMagic[] = "linecloud-hnsw-v1";

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

float Angle(float dot) {
  constexpr float kNorm = 1.0f / (512.0f * 512.0f);
  return std::acos(std::min(kNorm * dot, 1.0f));
}

}  // namespace

struct DescriptorIndex::Impl {
  std::span<const uint8_t> descriptors;
  hnswlib::L2Space space{kDim};
  std::unique_ptr<hnswlib::HierarchicalNSW<float>> graph;
  DescriptorIndexOptions options;
};

void DescriptorIndexOptions::Check() const {
  if (graph_degree < 2 || construction_ef < 2 || search_ef < 2 || threads < 1) {
    Fail("descriptor index: degree {}, construction ef {}, search ef {} and threads {} must be "
         "at least 2, 2, 2 and 1",
         graph_degree, construction_ef, search_ef, threads);
  }
}

DescriptorIndex::DescriptorIndex(std::span<const uint8_t> descriptors,
                                 const DescriptorIndexOptions& options)
    : impl_(std::make_unique<Impl>()) {
  options.Check();
  if (descriptors.size() % kDim != 0) Fail("descriptor index: rows of {} bytes expected", kDim);
  impl_->descriptors = descriptors;
  impl_->options = options;
  const size_t n = descriptors.size() / kDim;
  impl_->graph = std::make_unique<hnswlib::HierarchicalNSW<float>>(
      &impl_->space, std::max<size_t>(n, 1), options.graph_degree, options.construction_ef,
      /*random_seed=*/100);
  const auto add = [&](size_t begin, size_t step) {
    std::array<float, kDim> v;
    for (size_t i = begin; i < n; i += step) {
      ToFloat(descriptors.data() + i * kDim, v.data());
      impl_->graph->addPoint(v.data(), i);
    }
  };
  if (n > 0) {
    add(0, n);  // the first point alone: the graph's entry point
    std::vector<std::thread> workers;
    const size_t t = static_cast<size_t>(options.threads);
    for (size_t w = 0; w < t; ++w) {
      workers.emplace_back([&, w] {
        std::array<float, kDim> v;
        for (size_t i = 1 + w; i < n; i += t) {
          ToFloat(descriptors.data() + i * kDim, v.data());
          impl_->graph->addPoint(v.data(), i);
        }
      });
    }
    for (std::thread& w : workers) w.join();
  }
}

DescriptorIndex::~DescriptorIndex() = default;

size_t DescriptorIndex::size() const { return impl_->descriptors.size() / kDim; }

void DescriptorIndex::Save(const std::string& path) const {
  // hnswlib writes to a path: write it beside, then prepend our header.
  const std::string raw = path + ".hnswlib.tmp";
  impl_->graph->saveIndex(raw);
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
  if (!FileExists(path)) return nullptr;
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
  const std::string raw = path + ".hnswlib.tmp";
  WriteFileAtomically(raw, [&](std::ostream& os) { os << data.substr(magic.size() + 32); });
  std::unique_ptr<DescriptorIndex> index(new DescriptorIndex());
  index->impl_ = std::make_unique<Impl>();
  index->impl_->descriptors = descriptors;
  index->impl_->options = options;
  try {
    index->impl_->graph = std::make_unique<hnswlib::HierarchicalNSW<float>>(
        &index->impl_->space, raw, false, descriptors.size() / kDim);
  } catch (const std::exception&) {
    std::remove(raw.c_str());
    return nullptr;
  }
  std::remove(raw.c_str());
  if (index->impl_->graph->cur_element_count != descriptors.size() / kDim) return nullptr;
  return index;
}

std::vector<DescriptorMatch> DescriptorIndex::Match(std::span<const uint8_t> query,
                                                    const DescriptorMatchOptions& options) const {
  options.Check();
  if (options.cross_check) Fail("matching: the approximate index has no mutual check");
  if (query.size() % kDim != 0) Fail("matching: query rows of {} bytes expected", kDim);
  std::vector<DescriptorMatch> matches;
  if (size() < 2) return matches;
  impl_->graph->setEf(static_cast<size_t>(impl_->options.search_ef));
  std::array<float, kDim> v;
  const size_t nq = query.size() / kDim;
  for (size_t i = 0; i < nq; ++i) {
    const uint8_t* q = query.data() + i * kDim;
    ToFloat(q, v.data());
    auto result = impl_->graph->searchKnn(v.data(), 2);
    if (result.size() < 2) continue;
    const size_t second = result.top().second;
    result.pop();
    const size_t best = result.top().second;
    const float best_angle = Angle(Dot(q, impl_->descriptors.data() + best * kDim));
    const float second_angle = Angle(Dot(q, impl_->descriptors.data() + second * kDim));
    if (best_angle > options.max_distance || best_angle >= options.max_ratio * second_angle) {
      continue;
    }
    matches.push_back({static_cast<int>(i), static_cast<int>(best),
                       second_angle > 0 ? best_angle / second_angle : 1.0f});
  }
  return matches;
}

}  // namespace linecloud
