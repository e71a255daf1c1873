#include "linecloud/io/colmap_database.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "linecloud/io/track_descriptors.h"
#include "linecloud/testing/test_util.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

using testing::DataPath;
using testing::ErrorOf;
using testing::TempDir;

TEST(ColmapDatabase, PairIds) {
  EXPECT_EQ(ImagePairToPairId(1, 2), 2147483649u);
  EXPECT_EQ(ImagePairToPairId(2, 1), 2147483649u);
  EXPECT_EQ(PairIdToImagePair(6442450945u), std::make_pair(3u, 4u));
  for (uint32_t a : {1u, 7u, 100000u}) {
    for (uint32_t b : {2u, 9u, 2000000u}) {
      if (a >= b) continue;
      EXPECT_EQ(PairIdToImagePair(ImagePairToPairId(a, b)), std::make_pair(a, b));
    }
  }
}

TEST(ColmapDatabase, ReadsMaupertuis) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/colmap.db");
  const ColmapDatabase db(DataPath("colmap-maupertuis/colmap.db"));
  const auto cameras = db.ReadCameras();
  ASSERT_EQ(cameras.size(), 1u);
  EXPECT_EQ(cameras[0].model_id, CameraModelId::kSimplePinhole);
  EXPECT_EQ(cameras[0].width, 1919u);
  const auto images = db.ReadImages();
  ASSERT_EQ(images.size(), 4u);
  EXPECT_EQ(images[0].name, "00.jpg");
  EXPECT_EQ(images[3].name, "03.jpg");
  const FeatureKeypoints kp = db.ReadKeypoints(1);
  EXPECT_EQ(kp.rows(), 6424);
  EXPECT_EQ(kp.cols(), 6);
  EXPECT_NEAR(kp(0, 0), 1290.9084, 1e-3);
  const FeatureDescriptors desc = db.ReadDescriptors(1);
  EXPECT_EQ(desc.rows(), 6424);
  EXPECT_EQ(desc.cols(), 128);
  const auto matches = db.ReadAllMatches();
  ASSERT_EQ(matches.size(), 6u);
  EXPECT_EQ(matches[0].image_id1, 1u);
  EXPECT_EQ(matches[0].image_id2, 2u);
  EXPECT_EQ(matches[0].matches.rows(), 2516);
  // Asking for the pair the other way round swaps the columns.
  const FeatureMatches m12 = db.ReadMatches(1, 2), m21 = db.ReadMatches(2, 1);
  ASSERT_EQ(m12.rows(), m21.rows());
  EXPECT_EQ(m12.col(0), m21.col(1));
  for (int i = 0; i < m12.rows(); ++i) {
    ASSERT_LT(m12(i, 0), 6424u);
    ASSERT_LT(m12(i, 1), 5920u);
  }
  const auto geometries = db.ReadTwoViewGeometries();
  ASSERT_EQ(geometries.size(), 6u);
  EXPECT_EQ(geometries[0].inlier_matches.rows(), 2501);
  EXPECT_EQ(geometries[0].config, 3);
  EXPECT_GT(geometries[0].F.norm(), 0.0);
}

// Reading a database writes nothing beside it (COLMAP leaves databases in WAL
// mode, where even a read-only open creates -shm / -wal files).
TEST(ColmapDatabase, ReadingLeavesNoFileBehind) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/colmap.db");
  testing::TempDir tmp;
  std::filesystem::create_directories(tmp.Path("ro dir"));
  const std::string db = tmp.Path("ro dir/colmap.db");
  std::filesystem::copy_file(testing::DataPath("colmap-maupertuis/colmap.db"), db);
  {
    const ColmapDatabase database(db);
    EXPECT_EQ(database.ReadImages().size(), 4u);
  }
  size_t files = 0;
  for (const auto& e : std::filesystem::directory_iterator(tmp.Path("ro dir"))) {
    ++files;
    EXPECT_EQ(e.path().filename(), "colmap.db") << "created " << e.path();
  }
  EXPECT_EQ(files, 1u);
}

TEST(ColmapDatabase, DescriptorsPerPointFromTracks) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/colmap.db");
  const ColmapDatabase db(DataPath("colmap-maupertuis/colmap.db"));
  const Reconstruction rec = ReadColmapModel(DataPath("colmap-maupertuis/reconstruction"));
  const std::vector<uint64_t> ids = rec.SortedPoint3DIds();
  const PointDescriptors medoid =
      ComputePointDescriptors(rec, ids, db, DescriptorAggregation::kMedoid);
  const PointDescriptors mean = ComputePointDescriptors(rec, ids, db, DescriptorAggregation::kMean);
  ASSERT_EQ(medoid.dim, 128);
  ASSERT_EQ(medoid.data.size(), ids.size() * 128);
  // The medoid is one of the track's observed descriptors; the mean lies
  // within the per-dimension range of the track.
  for (size_t k = 0; k < ids.size(); ++k) {
    const Point3D& p = rec.points3D.at(ids[k]);
    bool found = false;
    for (const TrackElement& el : p.track) {
      const FeatureDescriptors d = db.ReadDescriptors(el.image_id);
      found |= std::equal(medoid.data.begin() + k * 128, medoid.data.begin() + (k + 1) * 128,
                          d.row(el.point2D_idx).data());
      if (k % 97 == 0) {
        // Spot check: mean is between min and max of the track.
        for (int c = 0; c < 128; ++c) {
          int lo = 255, hi = 0;
          for (const TrackElement& e2 : p.track) {
            const int v = db.ReadDescriptors(e2.image_id)(e2.point2D_idx, c);
            lo = std::min(lo, v);
            hi = std::max(hi, v);
          }
          ASSERT_GE(mean.data[k * 128 + c], lo);
          ASSERT_LE(mean.data[k * 128 + c], hi);
        }
      }
    }
    ASSERT_TRUE(found) << "point " << ids[k];
    if (k > 200) break;  // the rest is the same code path
  }
}

TEST(ColmapDatabase, BadFilesGiveErrorsNamingTheFile) {
  TempDir tmp;
  EXPECT_NE(ErrorOf([&] { ColmapDatabase db(tmp.Path("missing.db")); }).find("not found"),
            std::string::npos);
  std::ofstream(tmp.Path("text.db")) << "this is not a database, just text\n";
  const std::string not_db = ErrorOf([&] { ColmapDatabase db(tmp.Path("text.db")); });
  EXPECT_NE(not_db.find("text.db"), std::string::npos) << not_db;
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/colmap.db");
  const std::string full = ReadFileToString(DataPath("colmap-maupertuis/colmap.db"));
  std::ofstream(tmp.Path("cut.db"), std::ios::binary).write(full.data(), full.size() / 3);
  const std::string cut = ErrorOf([&] {
    ColmapDatabase db(tmp.Path("cut.db"));
    for (const DatabaseImage& im : db.ReadImages()) db.ReadDescriptors(im.image_id);
    db.ReadAllMatches();
    db.ReadTwoViewGeometries();
  });
  EXPECT_NE(cut.find("cut.db"), std::string::npos) << cut;
}

}  // namespace
}  // namespace linecloud
