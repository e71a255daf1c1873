// `linecloud bench match`: matching query descriptors to a map's, exact
// (MatchDescriptors) against the approximate indexes (DescriptorIndex: FAISS
// IVF and HNSW, hnswlib, FLANN), measured side by side in one run: index build
// time and memory, time for all queries on 1 and 2 threads, recall of the
// exact ratio-test matches.
// Descriptors are either
//   - real (`real_images`): SIFT (OpenCV's extractor, COLMAP's normalisation)
//     of real photos; the queries are the first photo's features, the map the
//     others' — each photo also mirrored and at 0.7x, whose descriptors differ,
//     until the map size is reached; or
//   - synthetic: seeded SIFT-like bytes (RootSIFT of gamma-distributed
//     histograms; queries half noisy copies of map descriptors, half unrelated).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "linecloud/features/descriptor_index.h"

namespace linecloud {

struct MatchBenchOptions {
  std::vector<size_t> map_sizes = {100000};
  size_t queries = 8000;
  size_t recall_queries = 1000;  // queries also matched exactly, for the recall
  uint64_t seed = 1;
  std::vector<DescriptorIndexKind> kinds = {DescriptorIndexKind::kFaissIvf,
                                            DescriptorIndexKind::kFlann};
  DescriptorIndexOptions index;  // kind ignored: each of `kinds`
  std::vector<int> threads = {1, 2};
  // Photos for real descriptors (the first gives the queries); empty: synthetic.
  std::vector<std::string> real_images;
  std::function<void(const std::string&)> progress;

  void Check() const;
};

// Every JPEG / PNG file under `dir` (recursively), sorted.
std::vector<std::string> PhotosUnder(const std::string& dir);

// The photos of the data folder (docs/data.md) for real descriptors: fountain-P11's 0000.jpg
// first (the queries), then fountain-P11's others, the other Strecha scenes,
// and every other JPEG / PNG under `data_dir`.
std::vector<std::string> RealBenchImages(const std::string& data_dir);

// SIFT descriptors (OpenCV's extractor, up to 32 768 a photo) of `images`:
// the originals, then mirrored, then at 0.7x, then mirrored at 0.7x, until
// `count` rows; throws Error when they give fewer.
std::vector<uint8_t> PhotoDescriptors(const std::vector<std::string>& images, size_t count,
                                      const std::function<void(const std::string&)>& progress);

// Real SIFT descriptors: `queries` rows from the first photo, then up to
// `map_size` rows from the others (originals, then mirrored, then at 0.7x).
struct RealDescriptors {
  std::vector<uint8_t> query, map;
};
RealDescriptors RealSiftDescriptors(const std::vector<std::string>& images, size_t queries,
                                    size_t map_size,
                                    const std::function<void(const std::string&)>& progress);

// One map size and index kind.
struct MatchBenchRow {
  size_t map_size = 0;
  bool real = false;  // real photos' descriptors, or synthetic ones
  std::string index;  // DescriptorIndexKindName
  size_t queries = 0;
  double index_build_s = 0, memory_mb = 0;
  std::map<int, double> ms_by_threads;  // all queries matched, by thread count
  double exact_ms_per_query = 0, exact_ms_extrapolated = 0;
  // On the recall queries: the exact matches, the index's, and the share of the exact ones the
  // index finds.
  size_t recall_queries = 0, exact_matches = 0, approx_matches = 0;
  double recall = 0;
};

std::vector<MatchBenchRow> RunMatchBench(const MatchBenchOptions& options);

// The rows as JSON (`bench match --json`) and as the Markdown table `linecloud bench match`
// prints.
nlohmann::json ToJson(const std::vector<MatchBenchRow>& rows);
std::string MatchBenchMarkdown(const std::vector<MatchBenchRow>& rows);

}  // namespace linecloud
