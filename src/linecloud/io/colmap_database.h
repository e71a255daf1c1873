// Read access to a COLMAP database (SQLite): cameras, images, keypoints,
// descriptors, matches and two-view geometries. Works with the schemas of
// COLMAP 3.x (only the columns common to all of them are read).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/camera.h"

struct sqlite3;

namespace linecloud {

using FeatureKeypoints = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using FeatureDescriptors = Eigen::Matrix<uint8_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using FeatureMatches = Eigen::Matrix<uint32_t, Eigen::Dynamic, 2, Eigen::RowMajor>;

struct DatabaseImage {
  uint32_t image_id = 0;
  std::string name;
  uint32_t camera_id = 0;
};

struct TwoViewGeometry {
  uint32_t image_id1 = 0;
  uint32_t image_id2 = 0;
  int config = 0;
  FeatureMatches inlier_matches;  // rows: (point2D_idx in image1, in image2)
  Eigen::Matrix3d F = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d E = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
};

struct ImagePairMatches {
  uint32_t image_id1 = 0;
  uint32_t image_id2 = 0;
  FeatureMatches matches;
};

// COLMAP's pair id: image_id1 * 2147483647 + image_id2 with image_id1 < image_id2.
uint64_t ImagePairToPairId(uint32_t image_id1, uint32_t image_id2);
std::pair<uint32_t, uint32_t> PairIdToImagePair(uint64_t pair_id);

class ColmapDatabase {
 public:
  // Opens read-only; throws Error naming the path when the file is missing,
  // not an SQLite database, or lacks COLMAP's tables.
  explicit ColmapDatabase(const std::string& path);
  ~ColmapDatabase();
  ColmapDatabase(const ColmapDatabase&) = delete;
  ColmapDatabase& operator=(const ColmapDatabase&) = delete;

  std::vector<Camera> ReadCameras() const;
  std::vector<DatabaseImage> ReadImages() const;
  // Empty matrices when the image has no entry.
  FeatureKeypoints ReadKeypoints(uint32_t image_id) const;
  FeatureDescriptors ReadDescriptors(uint32_t image_id) const;
  // Matches in the order (image_id1, image_id2) as asked, swapping columns when
  // COLMAP stored the pair the other way round.
  FeatureMatches ReadMatches(uint32_t image_id1, uint32_t image_id2) const;
  std::vector<ImagePairMatches> ReadAllMatches() const;
  std::vector<TwoViewGeometry> ReadTwoViewGeometries() const;
  // Images with a position prior (COLMAP fills it from the photo's EXIF GPS):
  // images.prior_tx/ty/tz not null and not all 0 (COLMAP 3.8), or the rows
  // of the pose_priors table (3.9 and later).
  size_t ImagesWithPositionPriors() const;

  const std::string& path() const { return path_; }

 private:
  std::string path_;
  sqlite3* db_ = nullptr;
};

}  // namespace linecloud
