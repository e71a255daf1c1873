#include "linecloud/mapping/sfm.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "linecloud/features/image.h"
#include "linecloud/features/matching.h"
#include "linecloud/io/colmap_database.h"
#include "linecloud/mapping/feature_database.h"
#include "linecloud/util/clock.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"
#include "linecloud/util/log.h"

namespace linecloud {
namespace fs = std::filesystem;
namespace {

std::string Threads(const SfmOptions& o) {
  return std::to_string(o.colmap.num_threads > 0 ? o.colmap.num_threads : o.threads);
}

// Runs `work(k)` for k in [0, n) on `threads` threads; the first error is
// rethrown after all stop.
void ParallelFor(size_t n, int threads, const std::function<void(size_t)>& work) {
  std::atomic<size_t> next{0};
  std::exception_ptr error;
  std::mutex mutex;
  auto run = [&] {
    for (size_t k; (k = next++) < n;) {
      try {
        work(k);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex);
        if (!error) error = std::current_exception();
        next = n;
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < std::max(1, threads); ++t) pool.emplace_back(run);
  run();
  for (std::thread& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

std::vector<std::pair<size_t, size_t>> ExhaustivePairs(size_t n) {
  std::vector<std::pair<size_t, size_t>> pairs;
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = i + 1; j < n; ++j) pairs.emplace_back(i, j);
  }
  return pairs;
}

// COLMAP's sequential pairs: each frame with its next `overlap` frames and
// the frames 2^k further on (its quadratic overlap), in name order.
std::vector<std::pair<size_t, size_t>> SequentialPairs(size_t n, int overlap) {
  std::set<std::pair<size_t, size_t>> pairs;
  for (size_t i = 0; i < n; ++i) {
    for (size_t d = 1; d <= size_t(overlap) && i + d < n; ++d) pairs.emplace(i, i + d);
    for (size_t d = size_t(overlap) * 2; i + d < n; d *= 2) pairs.emplace(i, i + d);
  }
  return {pairs.begin(), pairs.end()};
}

// Matches each pair here and hands them to COLMAP for verification in one
// raw match list (COLMAP's `matches_importer --match_type raw`).
MatchSummary MatchPairsHere(const std::vector<std::string>& names,
                            const std::vector<std::pair<size_t, size_t>>& pairs,
                            const std::string& database, const std::string& work_dir,
                            const SfmOptions& options, const SfmProgress& progress) {
  std::vector<FeatureDescriptors> descriptors(names.size());
  {
    const ColmapDatabase db(database);
    std::map<std::string, uint32_t> id;
    for (const DatabaseImage& im : db.ReadImages()) id[im.name] = im.image_id;
    for (size_t k = 0; k < names.size(); ++k) {
      const auto it = id.find(names[k]);
      if (it == id.end())
        Fail("{}: no features of {} (run the features stage)", database, names[k]);
      descriptors[k] = db.ReadDescriptors(it->second);
    }
  }
  DescriptorMatchOptions match;
  match.cross_check = true;  // COLMAP's SiftMatching defaults: ratio 0.8, distance 0.7, cross check
  std::vector<std::vector<DescriptorMatch>> found(pairs.size());  // per pair
  std::atomic<size_t> done{0};
  std::mutex progress_mutex;
  ParallelFor(pairs.size(), options.threads, [&](size_t k) {
    const auto& [i, j] = pairs[k];
    const FeatureDescriptors& a = descriptors[i];
    const FeatureDescriptors& b = descriptors[j];
    if (a.rows() > 0 && b.rows() > 0) {
      found[k] =
          MatchDescriptors({a.data(), size_t(a.size())}, {b.data(), size_t(b.size())}, match);
    }
    const size_t d = ++done;
    if (progress) {
      std::lock_guard<std::mutex> lock(progress_mutex);
      progress(d, pairs.size());
    }
  });
  MatchSummary summary;
  summary.pairs = pairs.size();
  const std::string list = JoinPaths(work_dir, "raw_matches.txt");
  WriteFileAtomically(list, [&](std::ostream& out) {
    for (size_t k = 0; k < pairs.size(); ++k) {
      if (found[k].size() < 15) continue;  // COLMAP's min_num_inliers: never verified
      out << names[pairs[k].first] << " " << names[pairs[k].second] << "\n";
      for (const DescriptorMatch& m : found[k]) out << m.query << " " << m.map << "\n";
      out << "\n";
      summary.raw_matches += found[k].size();
    }
  });
  RunColmapCommand({options.colmap.executable, "matches_importer", "--database_path", database,
                    "--match_list_path", list, "--match_type", "raw", "--random_seed",
                    std::to_string(options.seed), "--SiftMatching.use_gpu", "0",
                    "--SiftMatching.num_threads", Threads(options)},
                   JoinPaths(work_dir, "matches_importer.log"), options.colmap);
  return summary;
}

MatchSummary MatchByVocabTree(const std::string& database, const std::string& work_dir,
                              size_t num_photos, size_t num_features, const SfmOptions& options) {
  const std::string tree = JoinPaths(work_dir, "vocab_tree.bin");
  // A word per ~100 descriptors (COLMAP's trees: 32 K words for 1 000s of
  // photos, 256 K for 10 000s), at least 1 024.
  const size_t words = std::clamp<size_t>(num_features / 100, 1024, 262144);
  LogProgress("[map]   vocabulary tree: {} words from the project's {} descriptors ...", words,
              num_features);
  RunColmapCommand({options.colmap.executable, "vocab_tree_builder", "--database_path", database,
                    "--vocab_tree_path", tree, "--num_visual_words", std::to_string(words),
                    "--random_seed", std::to_string(options.seed)},
                   JoinPaths(work_dir, "vocab_tree_builder.log"), options.colmap);
  const int neighbours = std::min<int>(options.vocab_tree_neighbours, int(num_photos) - 1);
  RunColmapCommand({options.colmap.executable, "vocab_tree_matcher", "--database_path", database,
                    "--VocabTreeMatching.vocab_tree_path", tree, "--VocabTreeMatching.num_images",
                    std::to_string(neighbours), "--random_seed", std::to_string(options.seed),
                    "--SiftMatching.use_gpu", "0", "--SiftMatching.num_threads", Threads(options)},
                   JoinPaths(work_dir, "vocab_tree_matcher.log"), options.colmap);
  MatchSummary s;
  s.pairs = num_photos * size_t(neighbours);
  return s;
}

size_t CountVerifiedPairs(const std::string& database) {
  size_t n = 0;
  for (const TwoViewGeometry& g : ColmapDatabase(database).ReadTwoViewGeometries()) {
    n += g.inlier_matches.rows() > 0;
  }
  return n;
}

}  // namespace

PairSelection ParsePairSelection(const std::string& name, const std::string& option) {
  if (name == "auto") return PairSelection::kAuto;
  if (name == "exhaustive") return PairSelection::kExhaustive;
  if (name == "vocab-tree") return PairSelection::kVocabTree;
  if (name == "sequential") return PairSelection::kSequential;
  Fail("{}: '{}' (use auto, exhaustive, vocab-tree or sequential)", option, name);
}

const char* PairSelectionName(PairSelection pairs) {
  switch (pairs) {
    case PairSelection::kAuto:
      return "auto";
    case PairSelection::kExhaustive:
      return "exhaustive";
    case PairSelection::kVocabTree:
      return "vocab-tree";
    case PairSelection::kSequential:
      return "sequential";
  }
  return "?";
}

void SfmOptions::Check() const {
  colmap.Check();
  sift.Check();
  if (exhaustive_up_to < 2) Fail("exhaustive_up_to: {} < 2", exhaustive_up_to);
  if (sequential_overlap < 1 || sequential_overlap > 1000) {
    Fail("sequential overlap: {} (use 1 to 1000)", sequential_overlap);
  }
  if (vocab_tree_neighbours < 1) Fail("vocabulary tree neighbours: {} < 1", vocab_tree_neighbours);
  if (threads < 1 || threads > 1024) Fail("threads: {} (use 1 to 1024)", threads);
}

std::string SfmOptions::Describe() const {
  return fmt::format(
      "sift {} max_image_size={} max_num_features={} peak={} edge={}; pairs {} exhaustive<={} "
      "overlap={} neighbours={}; seed {}",
      SiftExtractorName(sift.extractor), sift.max_image_size, sift.max_num_features,
      sift.peak_threshold, sift.edge_threshold, PairSelectionName(pairs), exhaustive_up_to,
      sequential_overlap, vocab_tree_neighbours, seed);
}

size_t ExtractFeatures(const PhotoSet& photos, const std::string& database,
                       const SfmOptions& options, const SfmProgress& progress) {
  if (!FileExists(database)) {
    const std::string partial = database + ".partial";
    CreateColmapDatabase(partial, database + ".create.log", options.colmap);
    fs::rename(partial, database);
  }
  FeatureDatabaseWriter db(database);
  std::vector<uint32_t> camera_ids;
  for (const PhotoCamera& c : photos.cameras) {
    camera_ids.push_back(db.FindOrAddCamera(c.camera, c.prior_focal_length));
  }
  std::vector<size_t> todo;
  for (size_t k = 0; k < photos.photos.size(); ++k) {  // ids in name order
    const Photo& p = photos.photos[k];
    if (!db.HasFeatures(db.AddImage(p.name, camera_ids[p.camera], p.gps))) todo.push_back(k);
  }
  // Photos in parallel, each extractor on one thread: the same features on
  // any count (sift.h), and no thread idles on a photo's serial parts.
  std::mutex write_mutex;
  std::atomic<size_t> done{photos.photos.size() - todo.size()};
  SiftOptions sift = options.sift;
  sift.threads = 1;
  ParallelFor(todo.size(), options.threads, [&](size_t t) {
    const Photo& p = photos.photos[todo[t]];
    const std::string bytes = ReadFileToString(p.path);
    if (!p.blake2b.empty()) {
      InputFingerprint fp;
      fp.Add(bytes);
      if (fp.Hex() != p.blake2b) {
        Fail(
            "{}: the photo changed while the project was being built (its bytes are not those "
            "checked at the start); run the command again",
            p.path);
      }
    }
    const GreyImage image =
        DecodeGreyImage({reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()}, p.path);
    const SiftFeatures features = ExtractSift(image, sift);
    std::lock_guard<std::mutex> lock(write_mutex);
    db.WriteImage(p.name, camera_ids[p.camera], features, p.gps);
    if (progress) progress(++done, photos.photos.size());
  });
  size_t total = 0;
  const ColmapDatabase read(database);
  for (const DatabaseImage& im : read.ReadImages()) total += read.ReadKeypoints(im.image_id).rows();
  return total;
}

MatchSummary MatchPhotos(const PhotoSet& photos, const std::string& database,
                         const std::string& work_dir, const SfmOptions& options,
                         const std::vector<std::string>& only_with, const SfmProgress& progress) {
  CreateDirectories(work_dir);
  std::vector<std::string> names;
  for (const Photo& p : photos.photos) names.push_back(p.name);
  PairSelection selection = options.pairs;
  if (selection == PairSelection::kAuto) {
    selection = names.size() <= size_t(options.exhaustive_up_to) ? PairSelection::kExhaustive
                                                                 : PairSelection::kVocabTree;
  }
  {
    FeatureDatabaseWriter db(database);
    if (only_with.empty()) {
      db.ClearMatches();
    } else {
      std::vector<uint32_t> ids;
      for (const std::string& n : only_with) {
        if (const auto id = db.FindImage(n)) ids.push_back(*id);
      }
      db.ClearMatchesOf(ids);
    }
  }
  MatchSummary summary;
  if (selection == PairSelection::kVocabTree) {
    size_t features = 0;
    const ColmapDatabase read(database);
    for (const DatabaseImage& im : read.ReadImages())
      features += read.ReadKeypoints(im.image_id).rows();
    summary = MatchByVocabTree(database, work_dir, names.size(), features, options);
  } else {
    std::vector<std::pair<size_t, size_t>> pairs =
        selection == PairSelection::kSequential
            ? SequentialPairs(names.size(), options.sequential_overlap)
            : ExhaustivePairs(names.size());
    if (!only_with.empty()) {
      const std::set<std::string> fresh(only_with.begin(), only_with.end());
      std::erase_if(pairs, [&](const auto& p) {
        return !fresh.count(names[p.first]) && !fresh.count(names[p.second]);
      });
    }
    summary = MatchPairsHere(names, pairs, database, work_dir, options, progress);
  }
  summary.selection = PairSelectionName(selection);
  summary.verified = CountVerifiedPairs(database);
  return summary;
}

Reconstruction RunMapper(const std::string& database, const std::string& image_dir,
                         const std::string& sparse_dir, bool fix_intrinsics,
                         const SfmOptions& options) {
  fs::remove_all(sparse_dir);
  CreateDirectories(sparse_dir);
  std::vector<std::string> args = {options.colmap.executable,
                                   "mapper",
                                   "--database_path",
                                   database,
                                   "--image_path",
                                   image_dir,
                                   "--output_path",
                                   sparse_dir,
                                   "--random_seed",
                                   std::to_string(options.seed),
                                   "--Mapper.num_threads",
                                   Threads(options)};
  if (fix_intrinsics) {
    for (const char* o : {"--Mapper.ba_refine_focal_length", "--Mapper.ba_refine_principal_point",
                          "--Mapper.ba_refine_extra_params"}) {
      args.push_back(o);
      args.push_back("0");
    }
  }
  RunColmapCommand(args, JoinPaths(fs::path(sparse_dir).parent_path().string(), "mapper.log"),
                   options.colmap);
  return LargestModel(sparse_dir);
}

PhotoSet DatasetPhotoSet(const EvalDataset& dataset) {
  PhotoSet set;
  std::map<uint32_t, size_t> index;
  for (const auto& [id, camera] : dataset.cameras) {
    index[id] = set.cameras.size();
    set.cameras.push_back({camera, fmt::format("cameras.txt camera {}", id), true, true});
  }
  for (const std::string& name : dataset.images) {
    Photo p;
    p.path = JoinPaths(JoinPaths(dataset.dir, "images"), name);
    p.name = name;
    p.camera = index.at(dataset.image_camera.at(name));
    p.width = set.cameras[p.camera].camera.width;
    p.height = set.cameras[p.camera].camera.height;
    set.photos.push_back(std::move(p));
  }
  return set;
}

Reconstruction ReconstructDataset(const EvalDataset& dataset, const std::string& colmap_dir,
                                  const SfmOptions& options) {
  options.Check();
  CreateDirectories(colmap_dir);
  const PhotoSet photos = DatasetPhotoSet(dataset);
  InputFingerprint fp;
  fp.Add(ColmapVersion(options.colmap, colmap_dir));
  fp.Add(options.Describe());
  for (const PhotoCamera& c : photos.cameras) {
    fp.Add(fmt::format("{} {} {} {}", CameraModelName(c.camera.model_id), c.camera.width,
                       c.camera.height, fmt::join(c.camera.params, " ")));
  }
  for (const Photo& p : photos.photos) {
    fp.Add(p.name);
    fp.Add(std::to_string(p.camera));
    fp.AddFile(p.path);
  }
  const std::string fingerprint = fp.Hex();
  const std::string stamp = JoinPaths(colmap_dir, "fingerprint.txt");
  const std::string database = JoinPaths(colmap_dir, "database.db");
  const std::string sparse = JoinPaths(colmap_dir, "sparse");
  if (StampMatches(stamp, fingerprint)) {
    Reconstruction model = LargestModel(sparse);
    if (!model.images.empty()) {
      LogProgress("[eval] reusing the cached reconstruction in {} ({} images, {} points)", sparse,
                  model.images.size(), model.points3D.size());
      return model;
    }
  }
  fs::remove(stamp);
  fs::remove(database);
  auto t0 = std::chrono::steady_clock::now();
  LogProgress("[eval] SIFT of {} images ...", photos.photos.size());
  const size_t features = ExtractFeatures(photos, database, options);
  LogProgress("[eval]   {} features in {:.0f} s; matching ...", features, SecondsSince(t0));
  t0 = std::chrono::steady_clock::now();
  const MatchSummary m = MatchPhotos(photos, database, colmap_dir, options);
  LogProgress("[eval]   {} pairs ({}), {} verified, in {:.0f} s; mapping (intrinsics fixed) ...",
              m.pairs, m.selection, m.verified, SecondsSince(t0));
  t0 = std::chrono::steady_clock::now();
  Reconstruction model =
      RunMapper(database, JoinPaths(dataset.dir, "images"), sparse, true, options);
  if (model.images.empty()) {
    Fail("COLMAP's mapper reconstructed nothing (log {})", JoinPaths(colmap_dir, "mapper.log"));
  }
  LogProgress("[eval]   done in {:.0f} s: {} of {} images, {} points", SecondsSince(t0),
              model.images.size(), dataset.images.size(), model.points3D.size());
  WriteStamp(stamp, fingerprint);
  return model;
}

}  // namespace linecloud
