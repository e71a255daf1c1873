#include "linecloud/privacy/attack_bench.h"

#include <numeric>

#include <fmt/format.h>

#include "linecloud/lifting/lifting.h"
#include "linecloud/privacy/density_attack.h"
#include "linecloud/privacy/recovery_score.h"
#include "linecloud/synthetic/surfaces.h"
#include "linecloud/util/parallel.h"

namespace linecloud {

std::vector<AttackBenchRow> RunAttackBench(const AttackBenchOptions& o) {
  LiftingKey::Bytes bytes;
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<uint8_t>(0xA5 ^ (13 * i));
  const LiftingKey key(bytes);  // fixed: the same lines every run
  std::vector<AttackBenchRow> rows;
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
    rows.push_back({cloud.size(), WorkerThreads(o.threads), r.seconds,
                    1e6 * r.seconds / cloud.size(), ShareWithinDiagonal(s, 0.5),
                    ShareWithinDiagonal(s, 1.0), ShareWithinDiagonal(s, 2.0)});
  }
  return rows;
}

nlohmann::json ToJson(const std::vector<AttackBenchRow>& rows) {
  nlohmann::json j = nlohmann::json::array();
  for (const AttackBenchRow& r : rows) {
    j.push_back({{"lines", r.lines},
                 {"threads", r.threads},
                 {"seconds", r.seconds},
                 {"us_per_line", r.us_per_line},
                 {"within_0.5_percent", r.within_half_percent},
                 {"within_1_percent", r.within_1_percent},
                 {"within_2_percent", r.within_2_percent}});
  }
  return j;
}

std::string AttackBenchMarkdown(const std::vector<AttackBenchRow>& rows) {
  std::string md =
      "| lines | threads | seconds | µs per line | within 0.5 % / 1 % / 2 % of the diagonal |\n"
      "|---|---|---|---|---|\n";
  for (const AttackBenchRow& r : rows) {
    md += fmt::format("| {} | {} | {:.1f} | {:.0f} | {:.1f} % / {:.1f} % / {:.1f} % |\n", r.lines,
                      r.threads, r.seconds, r.us_per_line, 100 * r.within_half_percent,
                      100 * r.within_1_percent, 100 * r.within_2_percent);
  }
  return md;
}

}  // namespace linecloud
