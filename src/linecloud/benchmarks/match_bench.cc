#include "linecloud/benchmarks/match_bench.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <malloc.h>

#include <filesystem>
#include <set>
#include <string>

#include <fmt/format.h>

#include "linecloud/features/image.h"
#include "linecloud/features/matching.h"
#include "linecloud/features/sift.h"
#include "linecloud/util/clock.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using Clock = std::chrono::steady_clock;

// RootSIFT bytes of `v` (non-negative): sqrt(v / |v|₁) · 512, rounded, clamped.
void RootSiftBytes(const double* v, uint8_t* out) {
  double l1 = 0;
  for (int i = 0; i < 128; ++i) l1 += v[i];
  for (int i = 0; i < 128; ++i) {
    out[i] = static_cast<uint8_t>(std::clamp(std::round(512 * std::sqrt(v[i] / l1)), 0.0, 255.0));
  }
}

void RandomDescriptor(std::mt19937_64& rng, uint8_t* out) {
  std::gamma_distribution<double> gamma(0.5, 1.0);
  double v[128];
  for (double& x : v) x = gamma(rng) + 1e-9;
  RootSiftBytes(v, out);
}

// A noisy observation of `in`: per-bin gain and offset, back on the L2 sphere.
void NoisyCopy(std::mt19937_64& rng, const uint8_t* in, uint8_t* out) {
  std::normal_distribution<double> gain(0.0, 0.2), offset(0.0, 3.0);
  double v[128], norm = 0;
  for (int i = 0; i < 128; ++i) {
    v[i] = std::max(0.0, in[i] * std::exp(gain(rng)) + offset(rng));
    norm += v[i] * v[i];
  }
  const double s = norm > 0 ? 512 / std::sqrt(norm) : 0;
  for (int i = 0; i < 128; ++i)
    out[i] = static_cast<uint8_t>(std::clamp(std::round(v[i] * s), 0.0, 255.0));
}

// Bytes allocated on the heap now (glibc's allocator statistics): the
// growth across building an index is the memory the index holds.
size_t HeapBytes() { return mallinfo2().uordblks + mallinfo2().hblkhd; }

GreyImage Mirrored(const GreyImage& in) {
  GreyImage out = in;
  for (int y = 0; y < in.height; ++y) {
    std::reverse(out.pixels.begin() + size_t(y) * in.width,
                 out.pixels.begin() + size_t(y + 1) * in.width);
  }
  return out;
}

void Synthetic(const MatchBenchOptions& o, size_t n, std::vector<uint8_t>* map,
               std::vector<uint8_t>* query) {
  std::mt19937_64 rng(o.seed);
  map->assign(n * 128, 0);
  query->assign(o.queries * 128, 0);
  for (size_t i = 0; i < n; ++i) RandomDescriptor(rng, map->data() + i * 128);
  for (size_t i = 0; i < o.queries; ++i) {
    if (i % 2 == 0) {
      NoisyCopy(rng, map->data() + (rng() % n) * 128, query->data() + i * 128);
    } else {
      RandomDescriptor(rng, query->data() + i * 128);
    }
  }
}

}  // namespace

std::vector<std::string> PhotosUnder(const std::string& dir) {
  namespace fs = std::filesystem;
  std::vector<std::string> photos;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    const std::string ext = e.path().extension().string();
    if (e.is_regular_file() && (ext == ".jpg" || ext == ".png"))
      photos.push_back(e.path().string());
  }
  std::sort(photos.begin(), photos.end());
  return photos;
}

std::vector<std::string> RealBenchImages(const std::string& data_dir) {
  namespace fs = std::filesystem;
  const fs::path first = fs::path(data_dir) / "strecha/fountain-P11/images/0000.jpg";
  if (!fs::exists(first)) Fail("bench match --real: {} is missing", first.string());
  std::vector<std::string> others;
  for (std::string& p : PhotosUnder(data_dir)) {
    if (fs::path(p) != first) others.push_back(std::move(p));
  }
  // The query's own scene first (its true matches), then the other Strecha
  // scenes, then the rest.
  auto rank = [](const std::string& p) {
    return p.find("fountain-P11") != std::string::npos ? 0
           : p.find("strecha") != std::string::npos    ? 1
                                                       : 2;
  };
  std::sort(others.begin(), others.end(), [&](const std::string& a, const std::string& b) {
    return std::make_pair(rank(a), a) < std::make_pair(rank(b), b);
  });
  others.insert(others.begin(), first.string());
  return others;
}

std::vector<uint8_t> PhotoDescriptors(const std::vector<std::string>& images, size_t count,
                                      const std::function<void(const std::string&)>& progress) {
  std::vector<uint8_t> out;
  SiftOptions sift;
  sift.max_num_features = 32768;
  for (int variant = 0; variant < 4 && out.size() < count * 128; ++variant) {
    for (size_t i = 0; i < images.size() && out.size() < count * 128; ++i) {
      GreyImage image = ReadGreyImage(images[i]);
      if (variant >= 2) {
        image =
            DownscaleToMaxSize(image, std::max(8, int(0.7 * std::max(image.width, image.height))));
      }
      if (variant % 2 == 1) image = Mirrored(image);
      const SiftFeatures f = ExtractSift(image, sift);
      const size_t take = std::min(f.descriptors.size(), count * 128 - out.size());
      out.insert(out.end(), f.descriptors.begin(), f.descriptors.begin() + take);
      if (progress) progress(fmt::format("photo descriptors: {} of {}", out.size() / 128, count));
    }
  }
  if (out.size() < count * 128) {
    Fail("{} photos give {} descriptors, fewer than {}", images.size(), out.size() / 128, count);
  }
  return out;
}

RealDescriptors RealSiftDescriptors(const std::vector<std::string>& images, size_t queries,
                                    size_t map_size,
                                    const std::function<void(const std::string&)>& progress) {
  if (images.size() < 2) Fail("bench match: real descriptors need at least two photos");
  RealDescriptors out;
  SiftOptions query_sift;
  query_sift.max_num_features = static_cast<int>(queries);
  out.query = ExtractSift(ReadGreyImage(images[0]), query_sift).descriptors;
  if (out.query.size() < queries * 128) {
    Fail("bench match: {} gives {} features, fewer than the {} queries asked", images[0],
         out.query.size() / 128, queries);
  }
  out.map = PhotoDescriptors(std::vector<std::string>(images.begin() + 1, images.end()), map_size,
                             progress);
  return out;
}

void MatchBenchOptions::Check() const {
  if (map_sizes.empty()) Fail("bench match: no map size");
  for (const size_t n : map_sizes) {
    if (n < 2 || n > 20000000) Fail("bench match: map size {} is out of range [2, 2e7]", n);
  }
  if (queries < 1 || recall_queries < 1 || recall_queries > queries) {
    Fail("bench match: need 1 <= recall queries ({}) <= queries ({})", recall_queries, queries);
  }
  if (kinds.empty()) Fail("bench match: no index kind");
  for (const int t : threads) {
    if (t < 1 || t > 256) Fail("bench match: threads {} out of range [1, 256]", t);
  }
  index.Check();
}

std::vector<MatchBenchRow> RunMatchBench(const MatchBenchOptions& o) {
  o.Check();
  std::vector<MatchBenchRow> rows;
  const DescriptorMatchOptions match;
  for (const size_t n : o.map_sizes) {
    std::vector<uint8_t> map, query;
    if (o.real_images.empty()) {
      Synthetic(o, n, &map, &query);
    } else {
      RealDescriptors real = RealSiftDescriptors(o.real_images, o.queries, n, o.progress);
      map = std::move(real.map);
      query = std::move(real.query);
      query.resize(o.queries * 128);
    }
    const std::span<const uint8_t> recall_part(query.data(), o.recall_queries * 128);
    if (o.progress) o.progress(fmt::format("exact matching of {} queries", o.recall_queries));
    auto t = Clock::now();
    const std::vector<DescriptorMatch> exact = MatchDescriptors(recall_part, map, match);
    const double exact_ms = 1e3 * SecondsSince(t);
    for (const DescriptorIndexKind kind : o.kinds) {
      if (o.progress) {
        o.progress(
            fmt::format("{}: building over {} descriptors", DescriptorIndexKindName(kind), n));
      }
      DescriptorIndexOptions index_options = o.index;
      index_options.kind = kind;
      index_options.threads = 1;
      const size_t rss_before = HeapBytes();
      t = Clock::now();
      const DescriptorIndex index(map, index_options);
      const double build_s = SecondsSince(t);
      const double memory_mb = (double(HeapBytes()) - double(rss_before)) / 1e6;
      std::map<int, double> ms;
      std::vector<DescriptorMatch> approx;
      for (const int threads : o.threads) {
        t = Clock::now();
        approx = index.Match(query, match, threads);
        ms[threads] = 1e3 * SecondsSince(t);
      }
      std::set<std::pair<int, int>> found;
      for (const DescriptorMatch& m : approx) found.insert({m.query, m.map});
      size_t hits = 0;
      for (const DescriptorMatch& m : exact) hits += found.count({m.query, m.map});
      size_t approx_on_recall = 0;
      for (const DescriptorMatch& m : approx) approx_on_recall += m.query < int(o.recall_queries);
      rows.push_back({n, !o.real_images.empty(), std::string(DescriptorIndexKindName(kind)),
                      o.queries, build_s, memory_mb, ms, exact_ms / o.recall_queries,
                      exact_ms / o.recall_queries * o.queries, o.recall_queries, exact.size(),
                      approx_on_recall, exact.empty() ? 1.0 : double(hits) / exact.size()});
    }
  }
  return rows;
}

nlohmann::json ToJson(const std::vector<MatchBenchRow>& rows) {
  nlohmann::json j = nlohmann::json::array();
  for (const MatchBenchRow& r : rows) {
    nlohmann::json ms = nlohmann::json::object();
    for (const auto& [threads, v] : r.ms_by_threads) ms[std::to_string(threads)] = v;
    j.push_back({{"map_size", r.map_size},
                 {"descriptors", r.real ? "real" : "synthetic"},
                 {"index", r.index},
                 {"queries", r.queries},
                 {"index_build_s", r.index_build_s},
                 {"memory_mb", r.memory_mb},
                 {"ms_by_threads", ms},
                 {"exact_ms_per_query", r.exact_ms_per_query},
                 {"exact_ms_extrapolated", r.exact_ms_extrapolated},
                 {"recall_queries", r.recall_queries},
                 {"exact_matches", r.exact_matches},
                 {"approx_matches", r.approx_matches},
                 {"recall", r.recall}});
  }
  return j;
}

std::string MatchBenchMarkdown(const std::vector<MatchBenchRow>& rows) {
  const bool real = !rows.empty() && rows.front().real;
  std::string out = fmt::format(
      "bench match: {} query descriptors ({}), ratio 0.8\n"
      "| map size | index | build s | memory MB | ms, 1 thread | ms, 2 threads | exact ms "
      "(extrapolated) | recall of exact matches |\n|---|---|---|---|---|---|---|---|\n",
      rows.empty() ? 0 : rows.front().queries,
      real ? "real SIFT of fountain-P11 0000.jpg; map: the other photos"
           : "synthetic: half noisy copies of map descriptors");
  for (const MatchBenchRow& r : rows) {
    auto at = [&](int threads) {
      const auto it = r.ms_by_threads.find(threads);
      return it == r.ms_by_threads.end() ? std::string("-") : fmt::format("{:.0f}", it->second);
    };
    out += fmt::format(
        "| {} | {} | {:.1f} | {:.0f} | {} | {} | {:.0f} | {:.3f} ({} exact matches of {} "
        "queries) |\n",
        r.map_size, r.index, r.index_build_s, r.memory_mb, at(1), at(2), r.exact_ms_extrapolated,
        r.recall, r.exact_matches, r.recall_queries);
  }
  return out;
}

}  // namespace linecloud
