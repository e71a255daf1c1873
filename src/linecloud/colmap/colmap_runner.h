// COLMAP's command line (Debian package `colmap`, CPU only) as a subprocess,
// and the caches of its results: a run is skipped when a fingerprint of its
// inputs (COLMAP's version, cameras, image files, options) matches the one
// stored with it. The pipeline from photos to a model: mapping/sfm.h.
#pragma once

#include <array>
#include <string>
#include <string_view>
#include <vector>

#include <sodium.h>

#include "linecloud/io/colmap_model.h"

namespace linecloud {

struct ColmapOptions {
  std::string executable = "colmap";
  int num_threads = -1;  // COLMAP's default: all cores
  bool verbose = false;  // stream COLMAP's output instead of logging it to files

  void Check() const;
};

// A hash (BLAKE2b-256) of a stage's inputs, each added with its length: a
// cached result is reused only when the hash stored with it is equal.
class InputFingerprint {
 public:
  InputFingerprint();
  void Add(std::string_view s);
  void AddFile(const std::string& path);  // the file's bytes
  std::string Hex();

 private:
  crypto_generichash_state state_;
};

// COLMAP's version line ("COLMAP 3.8 ..."), asked once per process.
std::string ColmapVersion(const ColmapOptions& options, const std::string& log_dir);

// A cache stamp: `path` holds `fingerprint` (and a newline).
bool StampMatches(const std::string& path, const std::string& fingerprint);
void WriteStamp(const std::string& path, const std::string& fingerprint);

// The model folder under `sparse_dir` with the most registered images (empty
// when there is none).
Reconstruction LargestModel(const std::string& sparse_dir);

// Creates an empty COLMAP database (its own schema: `colmap database_creator`).
void CreateColmapDatabase(const std::string& path, const std::string& log_path,
                          const ColmapOptions& options);

// Runs `args` (argv[0] = COLMAP executable); output goes to `log_path`.
// Throws Error quoting the log's last lines when the command fails.
void RunColmapCommand(const std::vector<std::string>& args, const std::string& log_path,
                      const ColmapOptions& options);

// Maps only `image_names` (features and matches from `database_path`) into
// `out_dir`; the local reconstruction of a query group (its scale is
// arbitrary). Returns the model with the most registered images, or an empty
// Reconstruction when COLMAP could not initialise one. Cached like above.
Reconstruction ReconstructImageSubset(const std::string& database_path,
                                      const std::string& image_dir,
                                      const std::vector<std::string>& image_names,
                                      const std::string& out_dir, const ColmapOptions& options);

}  // namespace linecloud
