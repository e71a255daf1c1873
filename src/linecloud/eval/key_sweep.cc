#include "linecloud/util/log.h"
#include "linecloud/eval/key_sweep.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <random>

#include <fmt/format.h>

#include "linecloud/eval/direct_matching.h"
#include "linecloud/eval/eval_run.h"
#include "linecloud/solvers/minimal_problem.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"
#include "linecloud/util/statistics.h"

namespace linecloud {
namespace {

using ojson = nlohmann::ordered_json;

struct MethodTally {
  int queries = 0, successes = 0, localized = 0, wrong = 0;
  std::vector<double> ransac_ms, iterations;
  std::vector<double> rotation_z, position_z;  // a right pose's error / its reported σ

  static double Within(const std::vector<double>& z, double k) {
    if (z.empty()) return std::numeric_limits<double>::quiet_NaN();
    return static_cast<double>(
               std::count_if(z.begin(), z.end(), [k](double v) { return v <= k; })) /
           static_cast<double>(z.size());
  }

  KeySweepMethod Summary() const {
    KeySweepMethod m = Counts();
    m.covered_poses = static_cast<int>(rotation_z.size());
    m.rotation_within_1_sigma = Within(rotation_z, 1);
    m.rotation_within_3_sigma = Within(rotation_z, 3);
    m.position_within_1_sigma = Within(position_z, 1);
    m.position_within_3_sigma = Within(position_z, 3);
    return m;
  }

  KeySweepMethod Counts() const {
    return {queries,
            successes,
            localized,
            wrong,
            Mean(ransac_ms),
            Percentile(ransac_ms, 50),
            Percentile(ransac_ms, 99),
            ransac_ms.empty() ? 0.0 : *std::max_element(ransac_ms.begin(), ransac_ms.end()),
            Percentile(iterations, 50),
            iterations.empty() ? 0.0 : *std::max_element(iterations.begin(), iterations.end())};
  }
};

// What a rig's own cam_from_rig gets wrong (its worst camera against the truth): its poses'
// errors are judged beyond it, as every pose's is beyond the map's own error.
struct ErrorFloor {
  double rotation_deg = 0, translation = 0;
};

// One query's result (a row of direct matching's per_query / per_rig) into the tally and the
// report.
void Count(const KeySweepOptions& o, const DirectMatchingOptions& dm, const std::string& dataset,
           uint64_t key, const std::string& query, const std::string& method,
           const DirectMatchingAttempt& r, MethodTally* t, KeySweepReport* report,
           ErrorFloor floor = {}) {
  ++t->queries;
  const KeySweepAttempt a{dataset,
                          key,
                          query,
                          method,
                          r.success,
                          r.rotation_deg,
                          r.translation,
                          r.inliers,
                          r.iterations,
                          r.uniform_iterations,
                          r.ransac_ms,
                          r.sigma_px.value_or(0.0),
                          r.sigma_rotation_deg.value_or(0.0),
                          r.sigma_position.value_or(0.0),
                          r.stop_reason,
                          r.success ? std::string() : r.failure};
  report->queries.push_back(a);
  if (r.attempted) {
    t->ransac_ms.push_back(r.ransac_ms);
    t->iterations.push_back(r.iterations);
  }
  if (!r.success) {
    std::string reason = r.failure.empty() ? std::string("no pose") : r.failure;
    // The reason's kind, without its numbers.
    reason = reason.substr(0, reason.find_first_of("0123456789"));
    ++report->failures[reason];
    return;
  }
  ++t->successes;
  const bool localized =
      r.rotation_deg <= dm.max_rotation_deg && r.translation <= dm.max_translation;
  t->localized += localized;
  if (localized && r.sigma_rotation_deg && r.sigma_position) {
    t->rotation_z.push_back(std::max(0.0, r.rotation_deg - floor.rotation_deg) /
                            *r.sigma_rotation_deg);
    t->position_z.push_back(std::max(0.0, r.translation - floor.translation) / *r.sigma_position);
  }
  if (r.rotation_deg > o.wrong_rotation_deg || r.translation > o.wrong_translation) {
    ++t->wrong;
    report->wrong.push_back(a);
  }
}

}  // namespace

void KeySweepOptions::Check() const {
  if (work_dirs.empty()) Fail("eval keys: give at least one --work directory");
  if (out.empty()) Fail("eval keys: --out is required");
  if (keys < 1 || keys > 1000) Fail("eval keys: --keys must be in [1, 1000], got {}", keys);
  if (methods.empty() && rig_methods.empty()) Fail("eval keys: no --methods or --rig-methods");
  for (const std::string& m : methods) {
    if (FindMethod(m).multi) Fail("eval keys: --methods {} is a multi-camera method", m);
  }
  if (!(wrong_rotation_deg > 0) || !(wrong_translation > 0)) {
    Fail("eval keys: the wrong-pose thresholds must be positive");
  }
}

LiftingKey SweepKey(uint64_t i) {
  std::mt19937_64 rng(0x6c696e65636c6f75ULL ^ (i * 0x9e3779b97f4a7c15ULL));
  LiftingKey::Bytes bytes;
  for (uint8_t& b : bytes) b = static_cast<uint8_t>(rng() >> 56);
  return LiftingKey(bytes);
}

KeySweepReport RunKeySweep(const KeySweepOptions& options) {
  options.Check();
  DirectMatchingOptions dm;
  dm.methods = options.methods;
  dm.rig_methods = options.rig_methods;
  dm.image.sift.extractor = options.features;
  KeySweepReport report;
  report.keys = options.keys;
  report.first_key = options.first_key;
  report.features = SiftExtractorName(options.features);
  report.wrong_rotation_deg = options.wrong_rotation_deg;
  report.wrong_translation = options.wrong_translation;
  report.localized_rotation_deg = dm.max_rotation_deg;
  report.localized_translation = dm.max_translation;
  std::map<std::string, MethodTally> tallies, foreign_tallies;
  for (const std::string& work_dir : options.work_dirs) {
    const EvalWork work = ReadPreparedWork(work_dir);
    report.datasets.push_back(work.dataset);
    dm.extracted = std::make_shared<ExtractedPhotos>();  // each photo extracted once
    for (uint64_t k = options.first_key; k < options.first_key + options.keys; ++k) {
      const auto start = std::chrono::steady_clock::now();
      const DirectMatchingReport matched = RunDirectMatching(work, work_dir, SweepKey(k), dm);
      for (const DirectMatchingPhoto& row : matched.per_query) {
        for (const std::string& m : dm.methods) {
          Count(options, dm, work.dataset, k, row.image, m, row.methods.at(m), &tallies[m],
                &report);
        }
      }
      for (const DirectMatchingRig& row : matched.per_rig) {
        for (const std::string& m : dm.rig_methods) {
          if (const DirectMatchingAttempt* a = FindIn(row.methods, m))
            Count(options, dm, work.dataset, k, row.group, m, *a, &tallies[m], &report,
                  {row.rig_error_rotation_deg, row.rig_error_translation});
        }
      }
      if (options.other_place) {
        for (const std::string& other_dir : options.work_dirs) {
          if (other_dir == work_dir) continue;
          const EvalWork other = ReadPreparedWork(other_dir);
          const DirectMatchingReport foreign =
              RunOtherPlace(work, other, other_dir, SweepKey(k), dm);
          for (const DirectMatchingPhoto& row : foreign.per_query) {
            // A photo the point map localizes too sees that scene (fountain-P11's 0008-0009
            // show entry-P10's wall): not a photo of another place.
            const auto p3p = row.methods.find("p3P");
            if (p3p != row.methods.end() && p3p->second.success) {
              ++report.shared_views;
              continue;
            }
            for (const std::string& m : dm.methods) {
              Count(options, dm, work.dataset + " vs " + other.dataset, k, row.image, m,
                    row.methods.at(m), &foreign_tallies[m], &report);
            }
          }
        }
      }
      int wrong_so_far = 0;
      for (const auto& [name, t] : tallies) wrong_so_far += t.wrong;
      for (const auto& [name, t] : foreign_tallies) wrong_so_far += t.wrong;
      LogProgress("[keys] {} key {}: {:.1f} s, {} wrong successes so far", work.dataset, k,
                  std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
                  wrong_so_far);
    }
  }
  for (const auto& [name, t] : tallies) report.methods[name] = t.Summary();
  for (const auto& [name, t] : foreign_tallies) report.other_place[name] = t.Summary();
  WriteFileAtomically(options.out, [&](std::ostream& os) { os << ToJson(report).dump(2) << "\n"; });
  return report;
}

nlohmann::ordered_json ToJson(const KeySweepReport& r) {
  const auto summaries = [](const std::map<std::string, KeySweepMethod>& of) {
    ojson out = ojson::object();
    for (const auto& [name, m] : of) {
      out[name] = {{"queries", m.queries},
                   {"successes", m.successes},
                   {"localized", m.localized},
                   {"wrong", m.wrong},
                   {"ransac_ms",
                    {{"mean", m.ransac_ms_mean},
                     {"p50", m.ransac_ms_p50},
                     {"p99", m.ransac_ms_p99},
                     {"max", m.ransac_ms_max}}},
                   {"iterations", {{"p50", m.iterations_p50}, {"max", m.iterations_max}}}};
      if (m.covered_poses > 0) {
        out[name]["uncertainty_coverage"] = {{"poses", m.covered_poses},
                                             {"rotation",
                                              {{"within_1_sigma", m.rotation_within_1_sigma},
                                               {"within_3_sigma", m.rotation_within_3_sigma}}},
                                             {"position",
                                              {{"within_1_sigma", m.position_within_1_sigma},
                                               {"within_3_sigma", m.position_within_3_sigma}}}};
      }
    }
    return out;
  };
  const ojson methods = summaries(r.methods);
  ojson wrong = ojson::array(), queries = ojson::array();
  for (const KeySweepAttempt& a : r.wrong) {
    wrong.push_back({{"dataset", a.dataset},
                     {"key", a.key},
                     {"query", a.query},
                     {"method", a.method},
                     {"rotation_deg", a.rotation_deg},
                     {"translation", a.translation},
                     {"inliers", a.inliers},
                     {"sigma_px", a.sigma_px},
                     {"iterations", a.iterations},
                     {"stop_reason", a.stop_reason}});
  }
  for (const KeySweepAttempt& a : r.queries) {
    queries.push_back({{"dataset", a.dataset},
                       {"key", a.key},
                       {"query", a.query},
                       {"method", a.method},
                       {"success", a.success},
                       {"rotation_deg", a.rotation_deg},
                       {"translation", a.translation},
                       {"inliers", a.inliers},
                       {"iterations", a.iterations},
                       {"uniform_iterations", a.uniform_iterations},
                       {"ransac_ms", a.ransac_ms}});
    if (a.success) {
      queries.back()["sigma_rotation_deg"] = a.sigma_rotation_deg;
      queries.back()["sigma_position"] = a.sigma_position;
    }
    if (!a.failure.empty()) queries.back()["failure"] = a.failure;
  }
  ojson report;
  report["datasets"] = r.datasets;
  report["keys"] = {{"count", r.keys}, {"first", r.first_key}};
  report["features"] = r.features;
  report["thresholds"] = {
      {"wrong", {{"rotation_deg", r.wrong_rotation_deg}, {"translation", r.wrong_translation}}},
      {"localized",
       {{"rotation_deg", r.localized_rotation_deg}, {"translation", r.localized_translation}}}};
  report["methods"] = methods;
  if (!r.other_place.empty()) {
    report["other_place"] = summaries(r.other_place);
    report["other_place_shared_views"] = r.shared_views;
  }
  report["wrong"] = wrong;
  report["failures"] = r.failures;
  report["queries"] = queries;
  return report;
}

}  // namespace linecloud
