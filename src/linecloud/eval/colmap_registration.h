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

#include <string>

#include <nlohmann/json.hpp>

#include "linecloud/colmap/colmap_runner.h"

namespace linecloud {

struct ColmapRegistrationOptions {
  std::string work_dir, out_dir;
  std::string ours;  // optional: report.json of `eval run` (direct matching)
  ColmapOptions colmap;

  void Check() const;
};

// Writes OUT/colmap_registration.json and .md; returns the JSON.
nlohmann::ordered_json RunColmapRegistration(const ColmapRegistrationOptions& options);

}  // namespace linecloud
