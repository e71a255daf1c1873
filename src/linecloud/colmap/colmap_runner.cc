#include "linecloud/util/log.h"
#include "linecloud/colmap/colmap_runner.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <fmt/core.h>
#include <sodium.h>

#include "linecloud/lifting/key.h"
#include "linecloud/util/clock.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

extern char** environ;

namespace linecloud {
namespace fs = std::filesystem;

namespace {

std::string LastLines(const std::string& path, int n) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty()) lines.push_back(line);
  }
  std::string out;
  for (size_t i = lines.size() > size_t(n) ? lines.size() - n : 0; i < lines.size(); ++i) {
    out += "\n  " + lines[i];
  }
  return out;
}

class Fingerprint {
 public:
  Fingerprint() {
    EnsureSodiumInitialized();
    crypto_generichash_init(&state_, nullptr, 0, 32);
  }
  void Add(std::string_view s) {
    const uint64_t n = s.size();
    crypto_generichash_update(&state_, reinterpret_cast<const unsigned char*>(&n), sizeof(n));
    crypto_generichash_update(&state_, reinterpret_cast<const unsigned char*>(s.data()), s.size());
  }
  std::string Hex() {
    std::array<uint8_t, 32> out;
    crypto_generichash_final(&state_, out.data(), out.size());
    return ToHex(out);
  }

 private:
  crypto_generichash_state state_;
};

std::string ColmapVersion(const ColmapOptions& options, const std::string& log_dir) {
  const std::string log = JoinPaths(log_dir, "colmap_version.log");
  RunColmapCommand({options.executable, "help"}, log,
                   ColmapOptions{.executable = options.executable});
  std::ifstream in(log);
  std::string line;
  while (std::getline(in, line)) {
    if (line.find("COLMAP") != std::string::npos) return line;
  }
  return "unknown";
}

std::string CameraParams(const Camera& camera) {
  std::string s;
  for (double p : camera.params) s += fmt::format("{}{:.17g}", s.empty() ? "" : ",", p);
  return s;
}

// The model folder under `sparse_dir` with the most registered images.
Reconstruction LargestModel(const std::string& sparse_dir) {
  Reconstruction best;
  if (!IsDirectory(sparse_dir)) return best;
  std::vector<fs::path> dirs;
  for (const auto& e : fs::directory_iterator(sparse_dir)) {
    if (e.is_directory()) dirs.push_back(e.path());
  }
  std::sort(dirs.begin(), dirs.end());
  for (const fs::path& dir : dirs) {
    Reconstruction model = ReadColmapModel(dir.string());
    if (model.images.size() > best.images.size()) best = std::move(model);
  }
  return best;
}

std::string ThreadsArg(const ColmapOptions& o) { return std::to_string(o.num_threads); }

bool CacheValid(const std::string& stamp_path, const std::string& fingerprint) {
  return FileExists(stamp_path) && ReadFileToString(stamp_path) == fingerprint + "\n";
}

void WriteStamp(const std::string& stamp_path, const std::string& fingerprint) {
  WriteFileAtomically(stamp_path, [&](std::ostream& out) { out << fingerprint << "\n"; });
}

}  // namespace

void ColmapOptions::Check() const {
  if (executable.empty()) Fail("colmap executable: empty path");
  if (num_threads == 0 || num_threads < -1)
    Fail("colmap threads: {} (use -1 for all cores)", num_threads);
  if (max_image_size < 100) Fail("colmap max image size: {} < 100", max_image_size);
}

void RunColmapCommand(const std::vector<std::string>& args, const std::string& log_path,
                      const ColmapOptions& options) {
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (!options.verbose) {
    posix_spawn_file_actions_addopen(&actions, 1, log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                     0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
  }
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, args[0].c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    Fail("cannot run '{}': {} (install COLMAP: apt-get install colmap)", args[0],
         std::strerror(rc));
  }
  int status = 0;
  if (waitpid(pid, &status, 0) < 0) Fail("waiting for '{}' failed", args[0]);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    Fail("'{} {}' failed (exit status {}); log {}:{}", args[0], args.size() > 1 ? args[1] : "",
         WIFEXITED(status) ? WEXITSTATUS(status) : -1, log_path, LastLines(log_path, 8));
  }
}

Reconstruction ReconstructDataset(const EvalDataset& dataset, const std::string& colmap_dir,
                                  const ColmapOptions& options) {
  options.Check();
  CreateDirectories(colmap_dir);
  const std::string images_dir = JoinPaths(dataset.dir, "images");
  Fingerprint fp;
  fp.Add(ColmapVersion(options, colmap_dir));
  fp.Add(fmt::format("max_image_size={} accurate={}", options.max_image_size,
                     options.accurate_features));
  for (const auto& [id, camera] : dataset.cameras) {
    fp.Add(fmt::format("{} {} {} {} {}", id, CameraModelName(camera.model_id), camera.width,
                       camera.height, CameraParams(camera)));
  }
  for (const std::string& name : dataset.images) {
    fp.Add(name);
    fp.Add(std::to_string(dataset.image_camera.at(name)));
    fp.Add(ReadFileToString(JoinPaths(images_dir, name)));
  }
  const std::string fingerprint = fp.Hex();
  const std::string stamp = JoinPaths(colmap_dir, "fingerprint.txt");
  const std::string database = JoinPaths(colmap_dir, "database.db");
  const std::string sparse = JoinPaths(colmap_dir, "sparse");
  if (CacheValid(stamp, fingerprint)) {
    Reconstruction model = LargestModel(sparse);
    if (!model.images.empty()) {
      LogProgress("[eval] COLMAP: reusing the cached reconstruction in {} ({} images, {} points)",
                  sparse, model.images.size(), model.points3D.size());
      return model;
    }
  }
  fs::remove(stamp);
  fs::remove(database);
  fs::remove_all(sparse);
  CreateDirectories(sparse);

  auto t0 = std::chrono::steady_clock::now();
  for (const auto& [camera_id, camera] : dataset.cameras) {
    std::vector<std::string> names;
    for (const std::string& name : dataset.images) {
      if (dataset.image_camera.at(name) == camera_id) names.push_back(name);
    }
    if (names.empty()) continue;
    const std::string list = JoinPaths(colmap_dir, fmt::format("images_camera{}.txt", camera_id));
    WriteFileAtomically(list, [&](std::ostream& out) {
      for (const std::string& n : names) out << n << "\n";
    });
    LogProgress("[eval] COLMAP feature extraction: camera {} ({}), {} images ...", camera_id,
                CameraModelName(camera.model_id), names.size());
    RunColmapCommand(
        {options.executable,
         "feature_extractor",
         "--database_path",
         database,
         "--image_path",
         images_dir,
         "--image_list_path",
         list,
         "--ImageReader.camera_model",
         std::string(CameraModelName(camera.model_id)),
         "--ImageReader.camera_params",
         CameraParams(camera),
         "--ImageReader.single_camera",
         "1",
         "--SiftExtraction.use_gpu",
         "0",
         "--SiftExtraction.num_threads",
         ThreadsArg(options),
         "--SiftExtraction.max_image_size",
         std::to_string(options.max_image_size),
         "--SiftExtraction.estimate_affine_shape",
         options.accurate_features ? "1" : "0",
         "--SiftExtraction.domain_size_pooling",
         options.accurate_features ? "1" : "0"},
        JoinPaths(colmap_dir, fmt::format("feature_extractor_camera{}.log", camera_id)), options);
  }
  LogProgress("[eval]   done in {:.0f} s; exhaustive matching of {} images ...", SecondsSince(t0),
              dataset.images.size());
  t0 = std::chrono::steady_clock::now();
  RunColmapCommand(
      {options.executable, "exhaustive_matcher", "--database_path", database,
       "--SiftMatching.use_gpu", "0", "--SiftMatching.num_threads", ThreadsArg(options),
       "--SiftMatching.guided_matching", options.accurate_features ? "1" : "0"},
      JoinPaths(colmap_dir, "exhaustive_matcher.log"), options);
  LogProgress("[eval]   done in {:.0f} s; mapping (intrinsics fixed) ...", SecondsSince(t0));
  t0 = std::chrono::steady_clock::now();
  RunColmapCommand(
      {options.executable, "mapper", "--database_path", database, "--image_path", images_dir,
       "--output_path", sparse, "--Mapper.num_threads", ThreadsArg(options),
       "--Mapper.ba_refine_focal_length", "0", "--Mapper.ba_refine_principal_point", "0",
       "--Mapper.ba_refine_extra_params", "0"},
      JoinPaths(colmap_dir, "mapper.log"), options);
  Reconstruction model = LargestModel(sparse);
  if (model.images.empty())
    Fail("COLMAP's mapper reconstructed nothing (log {})", JoinPaths(colmap_dir, "mapper.log"));
  LogProgress("[eval]   done in {:.0f} s: {} of {} images, {} points", SecondsSince(t0),
              model.images.size(), dataset.images.size(), model.points3D.size());
  WriteStamp(stamp, fingerprint);
  return model;
}

Reconstruction ReconstructImageSubset(const std::string& database_path,
                                      const std::string& image_dir,
                                      const std::vector<std::string>& image_names,
                                      const std::string& out_dir, const ColmapOptions& options) {
  options.Check();
  CreateDirectories(out_dir);
  Fingerprint fp;
  fp.Add(ReadFileToString(database_path));
  for (const std::string& n : image_names) fp.Add(n);
  const std::string fingerprint = fp.Hex();
  const std::string stamp = JoinPaths(out_dir, "fingerprint.txt");
  const std::string sparse = JoinPaths(out_dir, "sparse");
  if (CacheValid(stamp, fingerprint)) return LargestModel(sparse);
  fs::remove(stamp);
  fs::remove_all(sparse);
  CreateDirectories(sparse);
  const std::string list = JoinPaths(out_dir, "images.txt");
  WriteFileAtomically(list, [&](std::ostream& out) {
    for (const std::string& n : image_names) out << n << "\n";
  });
  // A query group spans a short baseline: the initial pair may triangulate
  // at 4° instead of COLMAP's 16° (which it relaxes to 8° at most).
  try {
    RunColmapCommand({options.executable,
                      "mapper",
                      "--database_path",
                      database_path,
                      "--image_path",
                      image_dir,
                      "--image_list_path",
                      list,
                      "--output_path",
                      sparse,
                      "--Mapper.num_threads",
                      ThreadsArg(options),
                      "--Mapper.min_model_size",
                      "2",
                      "--Mapper.init_min_tri_angle",
                      "4",
                      "--Mapper.ba_refine_focal_length",
                      "0",
                      "--Mapper.ba_refine_principal_point",
                      "0",
                      "--Mapper.ba_refine_extra_params",
                      "0"},
                     JoinPaths(out_dir, "mapper.log"), options);
  } catch (const Error&) {
    // No model (e.g. no initial pair): a result too, cached like any other.
    fs::remove_all(sparse);
    CreateDirectories(sparse);
  }
  WriteStamp(stamp, fingerprint);
  return LargestModel(sparse);
}

}  // namespace linecloud
