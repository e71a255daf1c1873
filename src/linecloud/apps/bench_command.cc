#include <filesystem>
#include <iostream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "linecloud/apps/commands.h"
#include "linecloud/privacy/attack_bench.h"
#include "linecloud/benchmarks/feature_bench.h"
#include "linecloud/benchmarks/match_bench.h"
#include "linecloud/eval/photo_bench.h"
#include "linecloud/util/file.h"
#include "linecloud/benchmarks/localization_bench.h"
#include "linecloud/benchmarks/solver_bench.h"

namespace linecloud {
namespace {

struct BenchArgs {
  SolverBenchOptions options;
  bool json = false;
};

void RunBenchSolvers(const BenchArgs& args) {
  const SolverBenchReport report{args.options,
                                 RunSolverBench(args.options, [&](const std::string& what) {
                                   std::cerr << "bench: " << what << "\n";
                                 })};
  std::cout << (args.json ? ToJson(report).dump(2) + "\n" : SolverBenchMarkdown(report));
}

struct LocalizeBenchArgs {
  LocalizationBenchOptions options;
  bool json = false;
};

void RunBenchLocalize(const LocalizeBenchArgs& args) {
  const LocalizationBenchReport report{
      args.options, RunLocalizationBench(args.options, [&](const std::string& what) {
        std::cerr << "bench localize: " << what << "\n";
      })};
  std::cout << (args.json ? ToJson(report).dump(2) + "\n" : LocalizationBenchMarkdown(report));
}

// `linecloud bench solvers`: the minimal solvers against their peers.
void RegisterBenchSolvers(CLI::App* bench) {
  auto args = std::make_shared<BenchArgs>();
  CLI::App* solvers = bench->add_subcommand(
      "solvers",
      "Every minimal solver (and its peers: OpenGV, Eigen) on fixed-seed noise-free "
      "instances: µs per call, solutions, % true pose found, median log10 rotation "
      "error");
  solvers->add_flag("--json", args->json, "Print JSON");
  solvers->add_option("--seed", args->options.seed, "Random seed")->capture_default_str();
  solvers->add_option("--instances", args->options.instances, "Instances per method")
      ->capture_default_str();
  solvers->add_option("--min-time", args->options.min_seconds, "Seconds of timing per solver")
      ->capture_default_str();
  solvers->add_option("--methods", args->options.methods, "Only these methods")->delimiter(',');
  solvers->callback([args] { RunBenchSolvers(*args); });
}

// `linecloud bench localize`: every method on seeded synthetic queries.
void RegisterBenchLocalize(CLI::App* bench) {
  auto loc = std::make_shared<LocalizeBenchArgs>();
  CLI::App* localize = bench->add_subcommand(
      "localize",
      "Every method on the same seeded synthetic queries: accuracy, RANSAC statistics and "
      "time per query (RANSAC + refinement, one thread)");
  localize->add_flag("--json", loc->json, "Print JSON");
  localize->add_option("--seed", loc->options.seed, "Random seed")->capture_default_str();
  localize->add_option("--queries", loc->options.queries, "Queries per method")
      ->capture_default_str();
  localize
      ->add_option("--correspondences", loc->options.instance.num_correspondences,
                   "Correspondences per query")
      ->capture_default_str();
  localize
      ->add_option("--inlier-ratio", loc->options.instance.inlier_ratio, "Share of correct matches")
      ->capture_default_str();
  localize->add_option("--noise", loc->options.instance.noise_px, "Pixel noise (std. dev.)")
      ->capture_default_str();
  localize
      ->add_option("--local-noise", loc->options.instance.local_noise,
                   "+l point noise relative to depth")
      ->capture_default_str();
  localize
      ->add_option("--threshold", loc->options.localize.ransac.max_error, "RANSAC threshold (px)")
      ->capture_default_str();
  localize->add_option("--methods", loc->options.methods, "Only these methods")->delimiter(',');
  localize->add_flag("--scores", loc->options.instance.match_scores,
                     "Give each match a Lowe ratio drawn from those measured on real photos "
                     "(inliers and outliers apart), so RANSAC can sample the best first (PROSAC)");
  localize->add_flag("!--uniform", loc->options.localize.ransac.progressive_sampling,
                     "Uniform samples even when matches have scores (the reference for PROSAC)");
  localize->callback([loc] { RunBenchLocalize(*loc); });
}

// `linecloud bench match`: the approximate indexes against exact matching.
void RegisterBenchMatch(CLI::App* bench) {
  auto match = std::make_shared<MatchBenchOptions>();
  auto match_json = std::make_shared<bool>(false);
  auto match_kinds =
      std::make_shared<std::vector<std::string>>(std::vector<std::string>{"faiss-ivf", "flann"});
  auto match_real = std::make_shared<std::string>();
  CLI::App* m = bench->add_subcommand(
      "match",
      "Descriptor matching: the approximate indexes (FAISS IVF / HNSW, hnswlib, FLANN) against "
      "exact matching on real SIFT descriptors (--real) or seeded SIFT-like bytes: build time, "
      "memory, time on 1 and 2 threads, recall of the exact ratio-test matches");
  m->add_option("--map-sizes", match->map_sizes, "Map descriptor counts")->capture_default_str();
  m->add_option("--queries", match->queries, "Query descriptors")->capture_default_str();
  m->add_option("--recall-queries", match->recall_queries, "Queries also matched exactly (recall)")
      ->capture_default_str();
  m->add_option("--index", *match_kinds, "Indexes: faiss-ivf, faiss-hnsw, hnswlib, flann")
      ->capture_default_str();
  m->add_option("--threads", match->threads, "Thread counts to time")->capture_default_str();
  m->add_option(
      "--real", *match_real,
      "Real descriptors from the photos under this folder (the data folder, docs/data.md)");
  m->add_option("--nprobe", match->index.nprobe, "FAISS IVF: cells scanned per query")
      ->capture_default_str();
  m->add_option("--nlist", match->index.nlist, "FAISS IVF: cells (0: 4 sqrt(n))")
      ->capture_default_str();
  m->add_option("--ef-search", match->index.ef_search, "HNSW: candidate list when searching")
      ->capture_default_str();
  m->add_option("--checks", match->index.checks, "FLANN: kd-tree leaves visited per query")
      ->capture_default_str();
  m->add_option("--trees", match->index.trees, "FLANN: randomised kd-trees")->capture_default_str();
  m->add_option("--seed", match->seed, "Random seed (synthetic descriptors)")
      ->capture_default_str();
  m->add_flag("--json", *match_json, "Print JSON");
  m->callback([match, match_json, match_kinds, match_real] {
    match->kinds.clear();
    for (const std::string& k : *match_kinds) {
      match->kinds.push_back(ParseDescriptorIndexKind(k, "--index"));
    }
    if (!match_real->empty()) match->real_images = RealBenchImages(*match_real);
    match->progress = [](const std::string& s) { std::cerr << s << "\n"; };
    const std::vector<MatchBenchRow> rows = RunMatchBench(*match);
    std::cout << (*match_json ? ToJson(rows).dump(2) + "\n" : MatchBenchMarkdown(rows));
  });
}

// `linecloud bench photo`: a photo to a pose, per stage.
void RegisterBenchPhoto(CLI::App* bench) {
  auto photo = std::make_shared<PhotoBenchOptions>();
  auto photo_json = std::make_shared<bool>(false);
  auto photo_features =
      std::make_shared<std::vector<std::string>>(std::vector<std::string>{"colmap", "opencv"});
  CLI::App* ph = bench->add_subcommand(
      "photo",
      "A photo to a pose (JPEG bytes, decode, SIFT, matching, RANSAC, LM) on an eval work's "
      "queries against maps padded to a realistic size: per stage p50 / p99 for each extractor "
      "and thread count, with COLMAP's CLI extraction of the same photos");
  ph->add_option("--work", photo->work_dir, "work directory of `eval prepare`")->required();
  ph->add_option("--pad-to", photo->pad_to, "lines per map after padding (0: none)")
      ->capture_default_str();
  ph->add_option("--padding", photo->padding_dir,
                 "folder of other scenes' photos whose descriptors pad the maps "
                 "(e.g. DATA/strecha, docs/data.md)");
  ph->add_option("--features", *photo_features, "extractors: opencv, colmap")
      ->capture_default_str();
  ph->add_option("--threads", photo->threads, "thread counts")->capture_default_str();
  ph->add_option("--max-image-size", photo->max_image_size,
                 "photos with a larger side are downscaled before SIFT")
      ->capture_default_str();
  ph->add_option("--photos", photo->max_photos, "at most this many photos (0: all)")
      ->capture_default_str();
  ph->add_option("--colmap", photo->colmap, "COLMAP's executable (empty: no COLMAP peer)")
      ->capture_default_str();
  ph->add_flag("--json", *photo_json, "Print JSON");
  ph->callback([photo, photo_json, photo_features] {
    photo->extractors.clear();
    for (const std::string& f : *photo_features) {
      photo->extractors.push_back(ParseSiftExtractor(f, "--features"));
    }
    photo->progress = [](const std::string& s) { std::cerr << s << "\n"; };
    const PhotoBenchReport report = RunPhotoBench(*photo);
    std::cout << (*photo_json ? ToJson(report).dump(2) + "\n" : PhotoBenchMarkdown(report));
  });
}

// `linecloud bench attack`: the density attack per size.
void RegisterBenchAttack(CLI::App* bench) {
  auto attack = std::make_shared<AttackBenchOptions>();
  CLI::App* a = bench->add_subcommand(
      "attack",
      "The density attack (Chelani et al., CVPR 2021) on seeded dense façades: time "
      "and recovery per size");
  a->add_option("--sizes", attack->sizes, "Points (lines) per façade")->capture_default_str();
  a->add_option("--texture", attack->texture_share, "Share of points in texture spots")
      ->capture_default_str();
  a->add_option("--threads", attack->threads, "Threads (0: all cores)")->capture_default_str();
  a->add_option("--seed", attack->seed, "Random seed")->capture_default_str();
  a->callback([attack] {
    AttackBenchOptions o = *attack;
    o.progress = [](const std::string& s) { std::cerr << "bench attack: " << s << "\n"; };
    std::cout << AttackBenchMarkdown(RunAttackBench(o));
  });
}

// `linecloud bench features`: our SIFT against COLMAP's extractor.
void RegisterBenchFeatures(CLI::App* bench) {
  auto images = std::make_shared<std::vector<std::string>>();
  auto colmap = std::make_shared<std::string>("colmap");
  CLI::App* f = bench->add_subcommand(
      "features",
      "Our SIFT against COLMAP's CPU extractor on the same images: keypoints and "
      "descriptors that agree, ms per megapixel of each (one thread)");
  f->add_option("--image", *images, "Images (repeat)")->required();
  f->add_option("--colmap", *colmap, "COLMAP's command")->capture_default_str();
  f->callback([images, colmap] {
    std::cout << "| image | size | COLMAP keypoints | ours | same place and orientation | "
                 "descriptors identical / within ±1 | ours ms/MP | COLMAP CLI ms/MP | ratio |\n"
                 "|---|---|---|---|---|---|---|---|---|\n";
    const std::string scratch =
        JoinPaths(std::filesystem::temp_directory_path().string(), "linecloud-bench-features");
    for (const std::string& path : *images) {
      const std::filesystem::path p(path);
      const SiftAgreement a =
          CompareSiftWithColmap(p.parent_path().string(), p.filename().string(), scratch, *colmap);
      const double mp = a.width * a.height / 1e6;
      std::cout << fmt::format(
          "| {} | {}x{} | {} | {} | {} | {} / {} | {:.0f} | {:.0f} | {:.2f} |\n", path, a.width,
          a.height, a.colmap, a.ours, a.located, a.identical, a.within_one, a.ours_ms / mp,
          a.colmap_ms / mp, a.ours_ms / a.colmap_ms);
    }
  });
}

}  // namespace

void RegisterBenchCommand(CLI::App& app) {
  CLI::App* bench = app.add_subcommand("bench", "Benchmarks");
  bench->require_subcommand(1);
  RegisterBenchSolvers(bench);
  RegisterBenchLocalize(bench);
  RegisterBenchMatch(bench);
  RegisterBenchPhoto(bench);
  RegisterBenchAttack(bench);
  RegisterBenchFeatures(bench);
}

}  // namespace linecloud
