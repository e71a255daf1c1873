// `linecloud eval keys`: what an outsider with held-out photos sees of the
// success rule. A key changes a map's lines and so RANSAC's path through
// them; which photo, if any, gets a confident wrong pose depends on the key.
// Every query photo of each prepared dataset is matched straight to its
// group's map (the path of `localize --image`) with the map lifted under
// `keys` fixed, public keys, and every success is compared with the ground
// truth: a success farther than `wrong_rotation_deg` / `wrong_translation`
// from it is a wrong success — the answer a localizer must never give.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "linecloud/features/sift.h"
#include "linecloud/lifting/key.h"

namespace linecloud {

struct KeySweepOptions {
  std::vector<std::string> work_dirs;  // prepared by `eval prepare`
  std::string out;                     // JSON file
  int keys = 10;
  uint64_t first_key = 0;  // keys first_key, first_key + 1, ... (SweepKey)
  std::vector<std::string> methods = {"p6L"};
  std::vector<std::string> rig_methods = {"m-p6L"};
  SiftExtractor features = SiftOptions{}.extractor;
  double wrong_rotation_deg = 1.0;
  double wrong_translation = 0.5;  // work units (metres with ground truth)
  // Each work's photos also against every other work's first map: photos of
  // another place, whose every success is wrong (reported as "other place").
  bool other_place = false;

  void Check() const;
};

// The i-th key of the sweep: public and fixed (figures reproducible run to
// run; never a key for a real map).
LiftingKey SweepKey(uint64_t i);

// One method on one query photo (or a group's rig of photos) under one key.
struct KeySweepAttempt {
  std::string dataset;
  uint64_t key = 0;
  std::string query, method;
  bool success = false;
  double rotation_deg = 180, translation = 1e9;  // to the ground truth; 180 / 1e9: no pose
  int inliers = 0, iterations = 0, uniform_iterations = 0;
  double ransac_ms = 0;
  double sigma_px = 0;
  double sigma_rotation_deg = 0, sigma_position = 0;  // reported 1-σ (0: none)
  std::string stop_reason;
  std::string failure;  // why no pose ("" for a success)
};

struct KeySweepMethod {
  int queries = 0, successes = 0, localized = 0, wrong = 0;
  double ransac_ms_mean = 0, ransac_ms_p50 = 0, ransac_ms_p99 = 0, ransac_ms_max = 0;
  double iterations_p50 = 0, iterations_max = 0;
  // Over the localized successes (right poses): the share whose rotation and
  // centre errors are within 1 and 3 of the reported σ (LocalizeResult::
  // uncertainty, the matches' and the calibration's); NaN without one.
  int covered_poses = 0;
  double rotation_within_1_sigma = 0, rotation_within_3_sigma = 0;
  double position_within_1_sigma = 0, position_within_3_sigma = 0;
};

struct KeySweepReport {
  std::vector<std::string> datasets;
  int keys = 0;
  uint64_t first_key = 0;
  std::string features;
  double wrong_rotation_deg = 0, wrong_translation = 0;          // a success beyond: wrong
  double localized_rotation_deg = 0, localized_translation = 0;  // a success within: localized
  std::map<std::string, KeySweepMethod> methods;
  // Photos of another place (other_place), per method: every success is wrong.
  // Photos the other scene's point map localizes (p3P among the methods) see
  // that scene: counted in shared_views, not there.
  std::map<std::string, KeySweepMethod> other_place;
  int shared_views = 0;
  std::vector<KeySweepAttempt> wrong;    // the wrong successes
  std::map<std::string, int> failures;   // by the reason's kind (its text without numbers)
  std::vector<KeySweepAttempt> queries;  // every attempt
};

// Runs the sweep and writes options.out (ToJson).
KeySweepReport RunKeySweep(const KeySweepOptions& options);

// {"datasets", "keys", "features", "thresholds", "methods": {name: {"queries", "successes",
// "localized", "wrong", "ransac_ms": {"mean", "p50", "p99"}}}, "wrong": [...], "failures":
// {reason: count}, "queries": [...]}.
nlohmann::ordered_json ToJson(const KeySweepReport& report);

}  // namespace linecloud
