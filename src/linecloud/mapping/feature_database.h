// Writing a project's features into a COLMAP database (SQLite, the schema of
// `colmap database_creator`): cameras, images, keypoints and descriptors as
// COLMAP's feature extractor writes them, so that COLMAP's matchers and mapper
// take them as their own. Each image's rows go in one transaction: a process
// killed mid-way leaves whole images or none.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "linecloud/features/sift.h"
#include "linecloud/geometry/camera.h"

struct sqlite3;

namespace linecloud {

class FeatureDatabaseWriter {
 public:
  // Opens an existing COLMAP database for writing; throws Error naming it.
  explicit FeatureDatabaseWriter(const std::string& path);
  ~FeatureDatabaseWriter();
  FeatureDatabaseWriter(const FeatureDatabaseWriter&) = delete;
  FeatureDatabaseWriter& operator=(const FeatureDatabaseWriter&) = delete;

  // The id of a camera equal to `camera` (model, size, parameters), added when
  // there is none; `prior_focal_length`: COLMAP trusts its focal length.
  uint32_t FindOrAddCamera(const Camera& camera, bool prior_focal_length);
  // An image's id by name; nullopt when absent.
  std::optional<uint32_t> FindImage(const std::string& name) const;
  // True when the image has its keypoints and descriptors.
  bool HasFeatures(uint32_t image_id) const;
  // Adds the image without features (when absent) and returns its id: images
  // added in name order get ids in that order, whatever order their features
  // come in.
  uint32_t AddImage(const std::string& name, uint32_t camera_id,
                    const std::optional<Eigen::Vector3d>& gps);
  // Adds the image (or replaces its features) with keypoints as COLMAP's SIFT
  // extractor stores them (x, y and the affine shape of scale and orientation)
  // and its descriptors; `gps`: latitude, longitude, altitude as COLMAP 3.8
  // stores a photo's position prior. Returns the image id.
  uint32_t WriteImage(const std::string& name, uint32_t camera_id, const SiftFeatures& features,
                      const std::optional<Eigen::Vector3d>& gps);
  // Removes every match and two-view geometry (a matching stage begun anew).
  void ClearMatches();
  // Removes the matches and geometries of the pairs that involve `image_ids`.
  void ClearMatchesOf(const std::vector<uint32_t>& image_ids);

 private:
  void Exec(const char* sql);
  std::string path_;
  sqlite3* db_ = nullptr;
};

}  // namespace linecloud
