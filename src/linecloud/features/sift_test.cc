#include "linecloud/features/sift.h"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>

#include <gtest/gtest.h>

#include "linecloud/features/matching.h"
#include "linecloud/io/colmap_database.h"
#include "linecloud/testing/test_util.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using testing::SharedDataPath;
using testing::TempDir;

struct Agreement {
  size_t colmap = 0, ours = 0;
  size_t located = 0;      // COLMAP keypoints with one of ours within 0.05 px (same orientation)
  size_t identical = 0;    // ... whose descriptor is byte-identical
  size_t within_one = 0;   // ... or differs by at most 1 in every byte
};

// Our SIFT against COLMAP 3.8's CPU extractor (run here) on one image.
Agreement CompareWithColmap(const std::string& image_dir, const std::string& name,
                            const TempDir& tmp) {
  std::ofstream(tmp.Path("list.txt")) << name << "\n";
  const std::string db = tmp.Path("colmap.db");
  const std::string cmd = "colmap feature_extractor --database_path '" + db + "' --image_path '" +
                          image_dir + "' --image_list_path '" + tmp.Path("list.txt") +
                          "' --SiftExtraction.use_gpu 0 --SiftExtraction.num_threads 1 > '" +
                          tmp.Path("colmap.log") + "' 2>&1";
  if (std::system(cmd.c_str()) != 0) throw Error("colmap feature_extractor failed: " + cmd);
  const ColmapDatabase database(db);
  const FeatureKeypoints kp = database.ReadKeypoints(database.ReadImages().at(0).image_id);
  const FeatureDescriptors desc = database.ReadDescriptors(database.ReadImages().at(0).image_id);
  const SiftFeatures ours = ExtractSift(ReadGreyImage(image_dir + "/" + name));
  Agreement a;
  a.colmap = static_cast<size_t>(kp.rows());
  a.ours = ours.size();
  // Both lists come level by level in VLFeat's order: search a window.
  for (Eigen::Index i = 0; i < kp.rows(); ++i) {
    // COLMAP stores (x, y, a11, a12, a21, a22); orientation = atan2(a21, a11).
    const float x = kp(i, 0), y = kp(i, 1);
    const float angle = std::atan2(kp(i, 4 - 2 * (kp.cols() == 4)), kp(i, 2));
    // Same order expected: try the same index first, then everything.
    for (size_t step = 0; step <= ours.size(); ++step) {
      const size_t j = step == 0 ? static_cast<size_t>(i) : step - 1;
      if (j >= ours.size()) continue;
      const SiftKeypoint& k = ours.keypoints[j];
      if (std::abs(k.x - x) > 0.05f || std::abs(k.y - y) > 0.05f) continue;
      if (kp.cols() == 6 && std::abs(std::remainder(k.orientation - angle, 2 * std::numbers::pi)) > 1e-3) {
        continue;
      }
      ++a.located;
      int worst = 0;
      for (int b = 0; b < 128; ++b) {
        worst = std::max(worst, std::abs(int(desc(i, b)) - int(ours.descriptor(j)[b])));
      }
      a.identical += worst == 0;
      a.within_one += worst <= 1;
      break;
    }
  }
  return a;
}

TEST(Sift, ReproducesColmapsCpuExtractor) {
  LINECLOUD_REQUIRE_DATA("strecha/fountain-P11/images/0000.jpg");
  if (std::system("colmap -h > /dev/null 2>&1") != 0) {
    GTEST_SKIP() << "COLMAP's command line is not installed (apt-get install colmap)";
  }
  TempDir tmp;
  const Agreement a =
      CompareWithColmap(SharedDataPath("strecha/fountain-P11/images"), "0000.jpg", tmp);
  std::cout << "[ SIFT vs COLMAP 3.8 CPU, fountain-P11/0000.jpg ] COLMAP " << a.colmap << ", ours "
            << a.ours << ", located within 0.05 px " << a.located << ", descriptors identical "
            << a.identical << ", within ±1 " << a.within_one << "\n";
  ASSERT_GT(a.colmap, 1000u);
  EXPECT_GE(a.within_one, 0.95 * a.colmap);
}

}  // namespace
}  // namespace linecloud
