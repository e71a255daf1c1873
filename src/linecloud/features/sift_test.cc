#include "linecloud/features/sift.h"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>

#include <gtest/gtest.h>

#include "linecloud/benchmarks/feature_bench.h"
#include "linecloud/testing/test_util.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using testing::DataPath;
using testing::TempDir;

TEST(Sift, ReproducesColmapsCpuExtractor) {
  LINECLOUD_REQUIRE_DATA("strecha/fountain-P11/images/0000.jpg");
  if (std::system("colmap -h > /dev/null 2>&1") != 0) {
    LINECLOUD_ABSENT("COLMAP's command line is not installed (apt-get install colmap)");
  }
  TempDir tmp;
  const SiftAgreement a =
      CompareSiftWithColmap(DataPath("strecha/fountain-P11/images"), "0000.jpg", tmp.Path());
  std::cout << "[ SIFT vs COLMAP 3.8 CPU, fountain-P11/0000.jpg ] COLMAP " << a.colmap << ", ours "
            << a.ours << ", located within 0.05 px " << a.located << ", descriptors identical "
            << a.identical << ", within ±1 " << a.within_one << "\n";
  ASSERT_GT(a.colmap, 1000u);
  EXPECT_GE(a.within_one, 0.95 * a.colmap);
}

}  // namespace
}  // namespace linecloud
