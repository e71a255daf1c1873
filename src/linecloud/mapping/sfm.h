// Structure from motion from photos, the one pipeline of `linecloud map` and
// `eval prepare`: this project's SIFT (COLMAP's features, features/sift.h)
// written into a COLMAP database; pairs chosen by the photos' number and
// kind and matched here (COLMAP's matcher's tests: ratio, distance, cross
// check; features/matching.h), verified by COLMAP (`matches_importer`, its
// two-view geometry); COLMAP's mapper. Beyond `exhaustive_up_to` photos the
// pairs come from COLMAP's vocabulary tree built from the project's own
// descriptors (`vocab_tree_builder`, `vocab_tree_matcher`: nothing downloaded).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "linecloud/colmap/colmap_runner.h"
#include "linecloud/colmap/dataset.h"
#include "linecloud/features/sift.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/mapping/photo_set.h"

namespace linecloud {

enum class PairSelection {
  kAuto,        // exhaustive up to exhaustive_up_to photos, else the vocabulary tree
  kExhaustive,  // every pair
  kVocabTree,   // each photo with its most similar ones (COLMAP's vocabulary tree)
  kSequential,  // frames of a video, in name order: each with its next `overlap` and 2^k-th
};
// "auto", "exhaustive", "vocab-tree", "sequential"; throws Error naming `option`.
PairSelection ParsePairSelection(const std::string& name, const std::string& option);
const char* PairSelectionName(PairSelection pairs);

struct SfmOptions {
  ColmapOptions colmap;
  SiftOptions sift;  // sift.threads: the extractor's threads per photo
  PairSelection pairs = PairSelection::kAuto;
  int exhaustive_up_to = 100;
  int sequential_overlap = 10;
  int vocab_tree_neighbours = 40;  // VocabTreeMatching.num_images
  int threads = 2;                 // matching threads; COLMAP's when colmap.num_threads is -1
  uint64_t seed = 1;               // COLMAP's --random_seed

  void Check() const;
  // What changes the result (for stage fingerprints).
  std::string Describe() const;
};

// Progress of a stage: (done, total) counts.
using SfmProgress = std::function<void(size_t done, size_t total)>;

// Each photo's features into `database` (created when missing); photos that
// already have theirs are skipped, so a killed run continues where it was.
// Returns the features of all photos in total.
size_t ExtractFeatures(const PhotoSet& photos, const std::string& database,
                       const SfmOptions& options, const SfmProgress& progress = nullptr);

struct MatchSummary {
  std::string selection;   // the PairSelection used
  size_t pairs = 0;        // pairs matched
  size_t verified = 0;     // pairs with a two-view geometry
  size_t raw_matches = 0;  // matches before verification (exhaustive / sequential)
};

// Matches the photos' pairs and verifies them into `database`; `work_dir`
// holds the match lists and logs. `only_with`: when non-empty, only pairs
// with at least one of these photos (an update's new photos).
MatchSummary MatchPhotos(const PhotoSet& photos, const std::string& database,
                         const std::string& work_dir, const SfmOptions& options,
                         const std::vector<std::string>& only_with = {},
                         const SfmProgress& progress = nullptr);

// COLMAP's mapper into `sparse_dir` (emptied first); the intrinsics fixed
// when `fix_intrinsics`. Returns the model with the most registered images
// (empty when none).
Reconstruction RunMapper(const std::string& database, const std::string& image_dir,
                         const std::string& sparse_dir, bool fix_intrinsics,
                         const SfmOptions& options);

// The evaluation dataset's photos with their known cameras (fixed).
PhotoSet DatasetPhotoSet(const EvalDataset& dataset);

// `eval prepare`'s reconstruction of a dataset through the pipeline above
// into `colmap_dir` (database.db, sparse/<k>/): returns the model with the
// most registered images; reuses a cached result whose fingerprint matches.
Reconstruction ReconstructDataset(const EvalDataset& dataset, const std::string& colmap_dir,
                                  const SfmOptions& options);

}  // namespace linecloud
