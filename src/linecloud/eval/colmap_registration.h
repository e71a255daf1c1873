// `linecloud eval colmap`: the left-out query images of a prepared dataset
// registered by COLMAP itself on each group's point model — the reference a
// user of COLMAP would compare linecloud with ([image]). Per group: a copy of
// the dataset's COLMAP database without the group's images (a map owner's
// database), then, on one thread as linecloud's figures, `feature_extractor`
// on each query image (its known camera), `exhaustive_matcher` (the new pairs
// only) and `image_registrator` on the group's map; the registered poses are
// compared with the ground truth exactly as `eval run` compares its own.
//
// With `ours` (an `eval run` report.json with direct matching), the report
// sets linecloud's p6L and p3P figures for the same images beside COLMAP's.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "linecloud/colmap/colmap_runner.h"

namespace linecloud {

struct ColmapRegistrationOptions {
  std::string work_dir, out_dir;
  std::string ours;  // optional: report.json of `eval run` (direct matching)
  ColmapOptions colmap;

  void Check() const;
};

// A pose's error against the ground truth.
struct RegistrationError {
  double rotation_deg = 0, translation = 0;
};

// linecloud's figures for the image (direct matching in the `ours` report).
struct OursOnImage : RegistrationError {
  double seconds = 0;  // extract + match + the method's mean RANSAC and refinement
};

struct ColmapOnImage {
  double extract_s = 0, match_s = 0, register_s = 0;  // match and register: the group's share
  double seconds = 0;
  std::optional<RegistrationError> error;  // none: COLMAP did not register the image
};

struct RegistrationImage {
  std::string group, image;
  ColmapOnImage colmap;
  std::optional<std::map<std::string, OursOnImage>> ours;  // p6L, p3P; none without `ours`
};

struct RegistrationSummary {
  int images = 0, colmap_registered = 0;
  double colmap_median_rotation_deg = 0, colmap_median_translation = 0, colmap_mean_seconds = 0;
  // With `ours`: p6L over the same images.
  std::optional<double> p6l_median_rotation_deg, p6l_median_translation, p6l_mean_seconds;
};

struct ColmapRegistrationReport {
  std::string dataset, colmap_version, units;
  RegistrationSummary summary;
  std::vector<RegistrationImage> images;
};

// Writes OUT/colmap_registration.json and .md; returns the report.
ColmapRegistrationReport RunColmapRegistration(const ColmapRegistrationOptions& options);

nlohmann::ordered_json ToJson(const ColmapRegistrationReport& report);
// The summary of a colmap_registration.json (errors name `where` and the field).
RegistrationSummary RegistrationSummaryFromJson(const nlohmann::json& report,
                                                const std::string& where);
std::string ColmapRegistrationMarkdown(const ColmapRegistrationReport& report);

}  // namespace linecloud
