// The README's C++ example: a map loaded once, photos answered. Usage:
//   photos MAP.lcm "MODEL WIDTH HEIGHT PARAMS..." PHOTO.jpg [PHOTO.jpg ...]
// Each photo is localized twice, from its bytes in memory (as an HTTP body
// brings it) and from features extracted beforehand (as a device would send
// them); exits non-zero unless both give the same pose for every photo and,
// with --expect-success, every photo is localized.
#include <cstdio>
#include <cstring>
#include <string>

#include <linecloud/linecloud.h>
#include <linecloud/pipeline/localizer.h>
#include <linecloud/util/file.h>

using namespace linecloud;

int main(int argc, char** argv) {
  const bool expect_success = argc > 1 && std::strcmp(argv[1], "--expect-success") == 0;
  if (argc < 4 + expect_success) {
    std::fprintf(stderr, "usage: photos [--expect-success] MAP.lcm CAMERA PHOTO...\n");
    return 2;
  }
  try {
    // --- the example ---
    const Localizer localizer(ReadLineCloud(argv[1 + expect_success]));  // lines, index: once
    const Camera camera = ParseCameraString(argv[2 + expect_success]);
    int failures = 0;
    for (int i = 3 + expect_success; i < argc; ++i) {
      const std::string jpeg = ReadFileToString(argv[i]);  // or an HTTP body
      const std::span<const uint8_t> bytes(reinterpret_cast<const uint8_t*>(jpeg.data()),
                                           jpeg.size());
      const LocalizerResult r = localizer.LocalizeEncodedImage(bytes, camera);
      const Sim3d& cam_from_world = r.pose.query_from_world;
      // The time outside the photo's own stages: what the Localizer adds per request.
      const StageTimes& t = r.times;
      std::printf(
          "%s: %s, %d inliers, q = (%.6f %.6f %.6f %.6f), t = (%.4f %.4f %.4f), %.0f ms (decode "
          "%.0f, extract %.0f, match %.0f, prepare %.1f, ransac %.1f, refine %.1f, checks %.1f, "
          "other %.2f)\n",
          argv[i], r.success() ? "localized" : r.reason.c_str(),
          static_cast<int>(r.pose.inliers.size()), cam_from_world.rotation.w(),
          cam_from_world.rotation.x(), cam_from_world.rotation.y(), cam_from_world.rotation.z(),
          cam_from_world.translation.x(), cam_from_world.translation.y(),
          cam_from_world.translation.z(), t.total_ms, t.decode_ms, t.extract_ms, t.match_ms,
          t.prepare_ms, t.ransac_ms, t.refine_ms, t.check_ms, t.other_ms());
      // --- the check: the same photo from its features ---
      const SiftFeatures features = ExtractSift(DecodeGreyImage(bytes, argv[i]), {});
      const LocalizerResult f = localizer.LocalizeFeatures(features, camera);
      failures += f.pose.query_from_world.translation != cam_from_world.translation ||
                  f.success() != r.success() || (expect_success && !r.success());
    }
    return failures == 0 ? 0 : 1;
  } catch (const Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
