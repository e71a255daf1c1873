// Localizes one seeded synthetic query against a line cloud through the
// installed library, and exits non-zero unless the pose is the true one.
#include <cstdio>
#include <random>

#include <linecloud/linecloud.h>

int main() {
  using namespace linecloud;
  const MethodInfo& method = FindMethod("p6L");
  LocalizationInstanceOptions instance;
  instance.inlier_ratio = 0.5;
  instance.match_scores = true;
  std::mt19937_64 rng(42);
  const LocalizationInstance query = RandomLocalizationInstance(method, instance, rng);
  LocalizeOptions options;
  options.ransac.seed = 1;
  const LocalizeResult result = Localize(method, query.query, query.line_map, options);
  const LocalizationError error = CompareLocalization(result.query_from_world, query.truth);
  std::printf("linecloud %s: p6L %s, %d inliers of %d, rotation error %.4f deg, %d iterations\n",
              kLinecloudVersion, result.success ? "localized" : "failed",
              static_cast<int>(result.inliers.size()), result.num_correspondences,
              error.rotation_rad * 180 / 3.14159265358979, result.stats.iterations);
  return result.success && error.rotation_rad < 1e-2 ? 0 : 1;
}
