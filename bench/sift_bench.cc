// SIFT extraction of one real photo (Strecha fountain-P11 0000.jpg, 1536 x
// 1024, decoded once): the colmap extractor (VLFeat's features, our scale
// space, gradients and descriptors) on 1 and 2 threads, the same extractor on
// VLFeat's own code (the features COLMAP computes, the reference), and
// OpenCV's SIFT on 1 and 2 threads — all in the same run.
#include <cstdlib>
#include <filesystem>
#include <string>

#include <benchmark/benchmark.h>

#include "linecloud/features/image.h"
#include "linecloud/features/sift.h"
#include "linecloud/features/sift_opencv.h"
#include "linecloud/testing/data_dir.h"

namespace linecloud {
namespace {

// The photo, or nullptr when the data folder (testing/data_dir.h) does not hold it.
const GreyImage* Photo() {
  static const GreyImage* photo = []() -> const GreyImage* {
    const std::filesystem::path path = testing::DataPath("strecha/fountain-P11/images/0000.jpg");
    if (!std::filesystem::exists(path)) return nullptr;
    return new GreyImage(ReadGreyImage(path.string()));
  }();
  return photo;
}

void Extract(benchmark::State& state, SiftOptions options) {
  const GreyImage* photo = Photo();
  if (!photo) {
    static const std::string why = "real data absent: " + testing::DataPath("strecha") +
                                   " (scripts/get_data.sh, or set LINECLOUD_DATA)";
    state.SkipWithError(why.c_str());
    return;
  }
  // One untimed run first: the scale-space buffers are pooled, so the timed
  // runs measure the steady state of a process that extracts photo after photo.
  size_t features = ExtractSift(*photo, options).size();
  for (auto _ : state) features = ExtractSift(*photo, options).size();
  state.counters["features"] = static_cast<double>(features);
}

void BM_SiftColmap(benchmark::State& state) {
  SiftOptions options;
  options.extractor = SiftExtractor::kColmap;
  options.threads = static_cast<int>(state.range(0));
  Extract(state, options);
}
BENCHMARK(BM_SiftColmap)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_SiftColmapOnVlFeatsOwnCode(benchmark::State& state) {
  SiftOptions options;
  options.extractor = SiftExtractor::kColmap;
  options.vlfeat_scale_space = true;
  Extract(state, options);
}
BENCHMARK(BM_SiftColmapOnVlFeatsOwnCode)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_SiftOpenCV(benchmark::State& state) {
  SetOpenCVThreads(static_cast<int>(state.range(0)));
  SiftOptions options;
  options.extractor = SiftExtractor::kOpenCV;
  Extract(state, options);
  SetOpenCVThreads(1);
}
BENCHMARK(BM_SiftOpenCV)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace linecloud
