#include "linecloud/benchmarks/feature_bench.h"

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <numbers>

#include <fmt/format.h>

#include "linecloud/features/sift.h"
#include "linecloud/io/colmap_database.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

using Clock = std::chrono::steady_clock;

std::string Quote(const std::string& s) {
  std::string out = "'";
  for (const char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

}  // namespace

SiftAgreement CompareSiftWithColmap(const std::string& image_dir, const std::string& name,
                                    const std::string& work_dir, const std::string& colmap) {
  CreateDirectories(work_dir);
  const std::string list = JoinPaths(work_dir, "list.txt");
  const std::string db = JoinPaths(work_dir, "colmap.db");
  std::remove(db.c_str());
  WriteFileAtomically(list, [&](std::ostream& os) { os << name << "\n"; });
  const std::string cmd = Quote(colmap) + " feature_extractor --database_path " + Quote(db) +
                          " --image_path " + Quote(image_dir) + " --image_list_path " +
                          Quote(list) +
                          " --SiftExtraction.use_gpu 0 --SiftExtraction.num_threads 1 > " +
                          Quote(JoinPaths(work_dir, "colmap.log")) + " 2>&1";
  auto t = Clock::now();
  if (std::system(cmd.c_str()) != 0) {
    Fail("colmap feature_extractor failed on {} (log: {})", name,
         JoinPaths(work_dir, "colmap.log"));
  }
  SiftAgreement a;
  a.image = name;
  a.colmap_ms = 1e3 * std::chrono::duration<double>(Clock::now() - t).count();
  const ColmapDatabase database(db);
  const uint32_t id = database.ReadImages().at(0).image_id;
  const FeatureKeypoints kp = database.ReadKeypoints(id);
  const FeatureDescriptors desc = database.ReadDescriptors(id);
  t = Clock::now();
  const GreyImage image = ReadGreyImage(JoinPaths(image_dir, name));
  const SiftFeatures ours = ExtractSiftColmap(image);
  a.ours_ms = 1e3 * std::chrono::duration<double>(Clock::now() - t).count();
  a.width = image.width;
  a.height = image.height;
  a.colmap = static_cast<size_t>(kp.rows());
  a.ours = ours.size();
  for (Eigen::Index i = 0; i < kp.rows(); ++i) {
    // COLMAP stores (x, y, a11, a12, a21, a22): orientation atan2(a21, a11).
    const float x = kp(i, 0), y = kp(i, 1);
    const bool affine = kp.cols() == 6;
    const float angle = affine ? std::atan2(kp(i, 4), kp(i, 2)) : 0.0f;
    // Both lists come level by level in VLFeat's order: the same index first.
    for (size_t step = 0; step <= ours.size(); ++step) {
      const size_t j = step == 0 ? static_cast<size_t>(i) : step - 1;
      if (j >= ours.size()) continue;
      const SiftKeypoint& k = ours.keypoints[j];
      if (std::abs(k.x - x) > 0.05f || std::abs(k.y - y) > 0.05f) continue;
      if (affine && std::abs(std::remainder(k.orientation - angle, 2 * std::numbers::pi)) > 1e-3) {
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

nlohmann::json SiftAgreementToJson(const SiftAgreement& a) {
  const double mp = a.width * a.height / 1e6;
  return {{"image", a.image},
          {"width", a.width},
          {"height", a.height},
          {"colmap_keypoints", a.colmap},
          {"our_keypoints", a.ours},
          {"located", a.located},
          {"identical", a.identical},
          {"within_one", a.within_one},
          {"ours_ms_per_mp", a.ours_ms / mp},
          {"colmap_ms_per_mp", a.colmap_ms / mp}};
}

}  // namespace linecloud
