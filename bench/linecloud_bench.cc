// Foundation benchmarks (Google Benchmark, fixed seeds, one thread):
//   lifting throughput (points/s) against an unkeyed peer that draws the same
//   uniform directions from std::mt19937_64 — the price of the keyed PRF;
//   reading a 1 M-point binary COLMAP model against reading its bytes alone.
#include <filesystem>
#include <numeric>
#include <random>

#include <benchmark/benchmark.h>

#include "linecloud/io/colmap_model.h"
#include "linecloud/lifting/lifting.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

constexpr size_t kLiftPoints = 1 << 20;

struct LiftInput {
  std::vector<uint64_t> ids;
  std::vector<Eigen::Vector3d> points;
  LiftInput() {
    std::mt19937_64 rng(1);
    std::normal_distribution<double> g(0.0, 10.0);
    for (size_t i = 0; i < kLiftPoints; ++i) {
      ids.push_back(i + 1 + i / 1000);  // COLMAP-like: mostly consecutive
      points.emplace_back(g(rng), g(rng), g(rng));
    }
  }
};

const LiftInput& Input() {
  static const LiftInput input;
  return input;
}

LiftingKey BenchKey(DirectionSet directions = DirectionSet::kSphere) {
  LiftingKey::Bytes b{};
  std::iota(b.begin(), b.end(), 7);
  return LiftingKey(b, directions);
}

void BM_LiftPlucker(benchmark::State& state) {
  const LiftInput& in = Input();
  const LiftingKey key = BenchKey();
  for (auto _ : state) {
    LineCloud cloud = LiftPoints(in.ids, in.points, key, {LineEncoding::kPlucker});
    benchmark::DoNotOptimize(cloud.lines.data());
  }
  state.SetItemsProcessed(state.iterations() * in.ids.size());
}
BENCHMARK(BM_LiftPlucker)->Unit(benchmark::kMillisecond);

void BM_LiftCompact(benchmark::State& state) {
  const LiftInput& in = Input();
  const LiftingKey key = BenchKey(DirectionSet::kCompact256);
  for (auto _ : state) {
    LineCloud cloud = LiftPoints(in.ids, in.points, key, {LineEncoding::kCompact});
    benchmark::DoNotOptimize(cloud.lines.data());
  }
  state.SetItemsProcessed(state.iterations() * in.ids.size());
}
BENCHMARK(BM_LiftCompact)->Unit(benchmark::kMillisecond);

void BM_KeyedDirections(benchmark::State& state) {
  const LiftInput& in = Input();
  const LiftingKey key = BenchKey();
  std::vector<Eigen::Vector3d> directions(in.ids.size());
  for (auto _ : state) {
    KeyedDirections(key, in.ids, directions.data(), nullptr);
    benchmark::DoNotOptimize(directions.data());
  }
  state.SetItemsProcessed(state.iterations() * in.ids.size());
}
BENCHMARK(BM_KeyedDirections)->Unit(benchmark::kMillisecond);

// Peer: the same lines with directions from an unkeyed, non-permanent PRNG
// (what a naive lifting does). Ratio to BM_LiftPlucker = cost of the key.
void BM_PeerUnkeyedLift(benchmark::State& state) {
  const LiftInput& in = Input();
  std::vector<PluckerLine> lines(in.ids.size());
  for (auto _ : state) {
    std::mt19937_64 rng(42);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (size_t i = 0; i < in.ids.size(); ++i) {
      const double z = 1.0 - 2.0 * u(rng);
      const double r = std::sqrt(1.0 - z * z);
      const double phi = 2.0 * M_PI * u(rng);
      const Eigen::Vector3d v(r * std::cos(phi), r * std::sin(phi), z);
      lines[i] = PluckerLine(v, in.points[i].cross(v));
    }
    benchmark::DoNotOptimize(lines.data());
  }
  state.SetItemsProcessed(state.iterations() * in.ids.size());
}
BENCHMARK(BM_PeerUnkeyedLift)->Unit(benchmark::kMillisecond);

// A 1 M-point binary model: 200 images of 20 000 observations, tracks of 4.
class ModelFixture {
 public:
  ModelFixture() {
    dir_ = (std::filesystem::temp_directory_path() / "linecloud_bench_model").string();
    Reconstruction rec;
    Camera camera;
    camera.camera_id = 1;
    camera.model_id = CameraModelId::kSimpleRadial;
    camera.width = 1920;
    camera.height = 1080;
    camera.params = {1500, 960, 540, 0.01};
    rec.cameras[1] = camera;
    constexpr uint32_t kImages = 200;
    constexpr size_t kPoints = 1000000;
    constexpr int kTrack = 4;
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> u(0.0, 1000.0);
    for (uint32_t i = 1; i <= kImages; ++i) {
      Image& im = rec.images[i];
      im.image_id = i;
      im.camera_id = 1;
      im.name = "image_" + std::to_string(i) + ".jpg";
      im.cam_from_world.translation = Eigen::Vector3d(i, 0, 0);
    }
    rec.points3D.reserve(kPoints);
    for (size_t p = 0; p < kPoints; ++p) {
      Point3D& point = rec.points3D[p + 1];
      point.xyz = Eigen::Vector3d(u(rng), u(rng), u(rng));
      point.error = 0.5;
      for (int t = 0; t < kTrack; ++t) {
        const uint32_t image_id = static_cast<uint32_t>((p * 7 + t * 53) % kImages) + 1;
        Image& im = rec.images[image_id];
        point.track.push_back({image_id, static_cast<uint32_t>(im.points2D.size())});
        im.points2D.push_back({Eigen::Vector2d(u(rng), u(rng)), p + 1});
      }
    }
    WriteColmapModel(rec, dir_, ModelFormat::kBinary);
  }
  ~ModelFixture() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  const std::string& dir() const { return dir_; }

 private:
  std::string dir_;
};

const ModelFixture& Model() {
  static const ModelFixture fixture;
  return fixture;
}

void BM_ReadBinaryModel1M(benchmark::State& state) {
  const std::string& dir = Model().dir();
  for (auto _ : state) {
    Reconstruction rec = ReadColmapModel(dir);
    benchmark::DoNotOptimize(rec.points3D.size());
  }
  state.SetItemsProcessed(state.iterations() * 1000000);
}
BENCHMARK(BM_ReadBinaryModel1M)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// Peer: reading the same files' bytes without parsing them.
void BM_PeerReadBytesOnly1M(benchmark::State& state) {
  const std::string& dir = Model().dir();
  for (auto _ : state) {
    size_t total = 0;
    for (const char* f : {"cameras.bin", "images.bin", "points3D.bin"}) {
      total += ReadFileToString(JoinPaths(dir, f)).size();
    }
    benchmark::DoNotOptimize(total);
  }
}
BENCHMARK(BM_PeerReadBytesOnly1M)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace
}  // namespace linecloud

BENCHMARK_MAIN();
