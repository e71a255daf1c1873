#include "linecloud/privacy/attack_bench.h"

#include <numeric>

#include <fmt/format.h>

#include "linecloud/lifting/lifting.h"
#include "linecloud/privacy/density_attack.h"
#include "linecloud/privacy/recovery_score.h"
#include "linecloud/synthetic/surfaces.h"
#include "linecloud/util/parallel.h"

namespace linecloud {

nlohmann::json RunAttackBench(const AttackBenchOptions& o) {
  LiftingKey::Bytes bytes;
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<uint8_t>(0xA5 ^ (13 * i));
  const LiftingKey key(bytes);  // fixed: the same lines every run
  nlohmann::json rows = nlohmann::json::array();
  for (const int n : o.sizes) {
    FacadeOptions fo;
    fo.seed = o.seed;
    fo.num_points = n;
    fo.texture_share = o.texture_share;
    const std::vector<Eigen::Vector3d> points = SampleFacade(fo);
    std::vector<uint64_t> ids(points.size());
    std::iota(ids.begin(), ids.end(), 0);
    const LineCloud cloud = LiftPoints(ids, points, key, {});
    std::vector<Eigen::Vector3d> secret;
    for (const uint64_t id : PointIdsOfLines(key, cloud.ids)) secret.push_back(points[id]);
    DensityAttackOptions ao;
    ao.threads = o.threads;
    if (o.progress) {
      ao.progress = [&](const std::string& stage, size_t done, size_t total) {
        o.progress(fmt::format("{} lines: {} {:.0f} %", n, stage, 100.0 * done / total));
      };
    }
    const DensityAttackResult r = RunDensityAttack(cloud, ao);
    const RecoveryScore s = ScoreRecovery(r.points, secret, 0);
    rows.push_back({{"lines", cloud.size()},
                    {"threads", WorkerThreads(o.threads)},
                    {"seconds", r.seconds},
                    {"us_per_line", 1e6 * r.seconds / cloud.size()},
                    {"within_0.5_percent", ShareWithinDiagonal(s, 0.5)},
                    {"within_1_percent", ShareWithinDiagonal(s, 1.0)},
                    {"within_2_percent", ShareWithinDiagonal(s, 2.0)}});
  }
  return rows;
}

}  // namespace linecloud
