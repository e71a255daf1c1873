#include <iostream>
#include <thread>

#include "linecloud/apps/commands.h"
#include "linecloud/eval/eval_prepare.h"
#include "linecloud/eval/colmap_registration.h"
#include "linecloud/eval/eval_run.h"
#include "linecloud/eval/key_sweep.h"
#include "linecloud/eval/match_scores.h"
#include "linecloud/eval/privacy_tradeoff.h"
#include "linecloud/util/file.h"

namespace linecloud {

namespace {

// `linecloud eval prepare`.
void RegisterEvalPrepare(CLI::App* eval) {
  auto prepare_options = std::make_shared<EvalPrepareOptions>();
  CLI::App* prepare = eval->add_subcommand(
      "prepare",
      "COLMAP on all images (ground truth), one map per query group without its images, "
      "the group's own reconstruction (+l, rig), 2D-3D correspondences by indirect matching");
  prepare->add_option("--dataset", prepare_options->dataset_dir, "dataset directory")->required();
  prepare
      ->add_option("--work", prepare_options->work_dir,
                   "work directory (COLMAP results are cached here)")
      ->required();
  prepare
      ->add_option("--gravity-noise-deg", prepare_options->gravity_noise_deg,
                   "+u without an IMU: tilt of the ground-truth gravity, |N(0, sigma)| degrees")
      ->capture_default_str();
  prepare->add_option("--colmap", prepare_options->sfm.colmap.executable, "COLMAP executable")
      ->capture_default_str();
  prepare
      ->add_option("--threads", prepare_options->sfm.colmap.num_threads,
                   "threads of SIFT, matching and COLMAP (-1: all cores)")
      ->capture_default_str();
  prepare->add_flag("--verbose", prepare_options->sfm.colmap.verbose,
                    "show COLMAP's output instead of logging it");
  prepare->add_option("--seed", prepare_options->seed, "seed of the gravity noise")
      ->capture_default_str();
  prepare->callback([prepare_options] {
    const int t = prepare_options->sfm.colmap.num_threads;
    prepare_options->sfm.threads =
        t > 0 ? t : int(std::max(1u, std::thread::hardware_concurrency()));
    PrepareEvaluation(*prepare_options);
  });
}

// `linecloud eval privacy`.
void RegisterEvalPrivacy(CLI::App* eval) {
  auto tradeoff = std::make_shared<PrivacyTradeoffOptions>();
  auto tradeoff_quick = std::make_shared<bool>(false);
  CLI::App* privacy = eval->add_subcommand(
      "privacy",
      "privacy against accuracy: the density attack and localization on the maps of each lifting "
      "(plain, --sparsify uniform/balanced, --resist-attack, compact): tradeoff.md, .json, .png");
  auto render_only = std::make_shared<bool>(false);
  privacy->add_option("--work", tradeoff->work_dir, "work directory of `eval prepare`");
  privacy->add_option("--out", tradeoff->out_dir, "results directory")->required();
  privacy->add_flag("--render", *render_only,
                    "only redo tradeoff.md and .png from OUT/tradeoff.json");
  privacy->add_option("--methods", tradeoff->methods, "methods (paper protocol)")
      ->capture_default_str();
  privacy->add_flag("!--no-direct-matching", tradeoff->direct_matching,
                    "skip the direct matching of the query photos");
  privacy->add_flag("--quick", *tradeoff_quick,
                    "only plain, uniform 90 %, balanced 90 %, resist 0.2");
  auto specs = std::make_shared<std::vector<std::string>>();
  privacy->add_option(
      "--lifting", *specs,
      "liftings to measure instead of the default set (repeat): plain, uniform:F, "
      "balanced:F, resist:S, compact, or several joined by + (plain is always first)");
  privacy->callback([tradeoff, tradeoff_quick, specs, render_only] {
    PrivacyTradeoffOptions o = *tradeoff;
    if (*render_only) {
      RenderPrivacyTradeoff(o.out_dir);
      std::cout << ReadFileToString(JoinPaths(o.out_dir, "tradeoff.md"));
      return;
    }
    if (!specs->empty()) {
      o.liftings = {MapLifting{}};
      for (const std::string& spec : *specs) {
        const MapLifting l = ParseMapLifting(spec, "--lifting");
        if (l.Name() != "plain") o.liftings.push_back(l);
      }
    }
    if (*tradeoff_quick) o.liftings = QuickTradeoffLiftings();
    o.progress = [](const std::string& s) { std::cout << "[eval privacy] " << s << std::endl; };
    RunPrivacyTradeoff(o);
    std::cout << ReadFileToString(JoinPaths(o.out_dir, "tradeoff.md"));
  });
}

// `linecloud eval colmap`.
void RegisterEvalColmap(CLI::App* eval) {
  auto registration = std::make_shared<ColmapRegistrationOptions>();
  CLI::App* colmap = eval->add_subcommand(
      "colmap",
      "COLMAP itself registering the left-out query images on each group's point model "
      "(one thread), beside linecloud's figures: colmap_registration.md/.json");
  colmap->add_option("--work", registration->work_dir, "work directory of `eval prepare`")
      ->required();
  colmap->add_option("--out", registration->out_dir, "results directory")->required();
  colmap->add_option("--ours", registration->ours,
                     "report.json of `eval run` (direct matching) to set beside COLMAP's");
  colmap->add_option("--colmap", registration->colmap.executable, "COLMAP executable")
      ->capture_default_str();
  colmap->callback([registration] {
    RunColmapRegistration(*registration);
    std::cout << ReadFileToString(JoinPaths(registration->out_dir, "colmap_registration.md"));
  });
}

// `linecloud eval scores`.
void RegisterEvalScores(CLI::App* eval) {
  auto scores = std::make_shared<MatchScoreOptions>();
  CLI::App* scores_cmd = eval->add_subcommand(
      "scores",
      "match scores on real photos: Lowe-ratio histograms of true inliers and outliers "
      "(ground-truth reprojection), inlier share of the best-ranked matches (JSON)");
  scores_cmd->add_option("--work", scores->work_dirs, "work directories of `eval prepare` (repeat)")
      ->required();
  scores_cmd->add_option("--out", scores->out, "JSON file")->required();
  scores_cmd->add_option("--inlier-px", scores->inlier_px, "ground-truth inlier threshold (px)")
      ->capture_default_str();
  scores_cmd->add_option("--bins", scores->bins, "histogram bins")->capture_default_str();
  scores_cmd->callback([scores] {
    const nlohmann::ordered_json report = ToJson(RunMatchScores(*scores));
    std::cout << report["histogram"].dump() << "\n" << report["top_share"].dump() << "\n";
  });
}

// `linecloud eval keys`.
void RegisterEvalKeys(CLI::App* eval) {
  auto sweep = std::make_shared<KeySweepOptions>();
  auto sweep_features = std::make_shared<std::string>(SiftExtractorName(sweep->features));
  CLI::App* keys_cmd = eval->add_subcommand(
      "keys",
      "held-out photos against their group's map lifted under many fixed keys: successes, "
      "localized, wrong successes (beyond --wrong-rotation / --wrong-translation) (JSON)");
  keys_cmd->add_option("--work", sweep->work_dirs, "work directories of `eval prepare` (repeat)")
      ->required();
  keys_cmd->add_option("--out", sweep->out, "JSON file")->required();
  keys_cmd->add_option("--keys", sweep->keys, "keys per map")->capture_default_str();
  keys_cmd->add_option("--first-key", sweep->first_key, "index of the first key")
      ->capture_default_str();
  keys_cmd->add_option("--methods", sweep->methods, "one-photo methods")->capture_default_str();
  keys_cmd->add_option("--rig-methods", sweep->rig_methods, "methods for each group's photos")
      ->capture_default_str();
  keys_cmd->add_option("--features", *sweep_features, "colmap or opencv")->capture_default_str();
  keys_cmd->add_option("--wrong-rotation", sweep->wrong_rotation_deg, "degrees")
      ->capture_default_str();
  keys_cmd->add_option("--wrong-translation", sweep->wrong_translation, "work units (metres)")
      ->capture_default_str();
  keys_cmd->add_flag("--other-place", sweep->other_place,
                     "each work's photos also against every other work's first map (photos of "
                     "another place: every success is wrong)");
  keys_cmd->callback([sweep, sweep_features] {
    sweep->features = ParseSiftExtractor(*sweep_features, "--features");
    const nlohmann::ordered_json report = ToJson(RunKeySweep(*sweep));
    std::cout << report["methods"].dump(1) << "\n";
    if (!report["wrong"].empty())
      std::cout << "wrong successes: " << report["wrong"].dump(1) << "\n";
  });
}

// `linecloud eval run`.
void RegisterEvalRun(CLI::App* eval) {
  auto run_options = std::make_shared<EvalRunOptions>();
  auto no_sweeps = std::make_shared<bool>(false);
  CLI::App* run = eval->add_subcommand(
      "run", "the 16 methods on the prepared correspondences: report.json, report.md, PNG plots");
  run->add_option("--work", run_options->work_dir, "work directory of `eval prepare`")->required();
  run->add_option("--out", run_options->out_dir, "results directory")->required();
  run->add_option("--methods", run_options->methods, "methods to run (default: all 16)");
  auto sparsify_mode = std::make_shared<std::string>("uniform");
  run->add_option("--sparsify", run_options->lifting.sparsify,
                  "share of map points/lines dropped (keyed, as lift --sparsify)")
      ->capture_default_str();
  run->add_option("--sparsify-mode", *sparsify_mode,
                  "uniform or balanced (as lift --sparsify-mode)")
      ->check(CLI::IsMember({"uniform", "balanced"}))
      ->capture_default_str();
  run->add_option("--resist-attack", run_options->lifting.resist_attack,
                  "as lift --resist-attack (after --sparsify); negative: off")
      ->capture_default_str();
  run->add_flag("--compact", run_options->lifting.compact,
                "the compact encoding (lines of a compact256 key derived from the evaluation's)");
  run->add_option("--noise", run_options->noise_px, "Gaussian noise (px) added to the query pixels")
      ->capture_default_str();
  run->add_option("--threshold", run_options->threshold_px, "RANSAC inlier threshold (px)")
      ->capture_default_str();
  run->add_option("--seed", run_options->seed, "RANSAC seed")->capture_default_str();
  run->add_option("--density-sweep", run_options->density_sweep,
                  "dropped shares for the density plot")
      ->capture_default_str();
  run->add_option("--noise-sweep", run_options->noise_sweep,
                  "synthetic pixel noise levels for the noise plot")
      ->capture_default_str();
  run->add_option("--noise-queries", run_options->noise_sweep_queries,
                  "synthetic queries per noise level")
      ->capture_default_str();
  run->add_flag("--no-sweeps", *no_sweeps, "skip the density and noise sweeps (and their plots)");
  run->add_flag("!--no-direct-matching", run_options->direct_matching,
                "skip the direct-matching protocol (query images' own SIFT features)");
  auto features = std::make_shared<std::string>(SiftExtractorName(SiftOptions{}.extractor));
  run->add_option("--features", *features,
                  "direct matching's SIFT: colmap (identical to COLMAP's extractor) or opencv")
      ->capture_default_str();
  run->callback([run_options, no_sweeps, sparsify_mode, features] {
    EvalRunOptions o = *run_options;
    o.features = ParseSiftExtractor(*features, "--features");
    o.lifting.sparsify_mode = SparsifyModeFromName(*sparsify_mode, "--sparsify-mode");
    if (*no_sweeps) {
      o.density_sweep.clear();
      o.noise_sweep.clear();
    }
    RunEvaluation(o);
  });
}

}  // namespace

void RegisterEvalCommand(CLI::App& app) {
  CLI::App* eval = app.add_subcommand(
      "eval", "The paper's experiments on a real image dataset (layout: docs/data.md)");
  eval->require_subcommand(1);

  RegisterEvalPrepare(eval);
  RegisterEvalPrivacy(eval);
  RegisterEvalColmap(eval);
  RegisterEvalScores(eval);
  RegisterEvalKeys(eval);
  RegisterEvalRun(eval);
}

}  // namespace linecloud
