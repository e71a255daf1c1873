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
  std::vector<double> ransac_ms;
};

// One query's result (a row of direct matching's per_query / per_rig) into the tally.
void Count(const KeySweepOptions& o, const DirectMatchingOptions& dm, const std::string& dataset,
           uint64_t key, const std::string& query, const std::string& method,
           const DirectMatchingAttempt& r, MethodTally* t, ojson* wrong, ojson* queries,
           std::map<std::string, int>* failures) {
  ++t->queries;
  queries->push_back({{"dataset", dataset},
                      {"key", key},
                      {"query", query},
                      {"method", method},
                      {"success", r.success},
                      {"rotation_deg", r.rotation_deg},
                      {"translation", r.translation},
                      {"inliers", r.inliers},
                      {"iterations", r.iterations},
                      {"uniform_iterations", r.uniform_iterations},
                      {"ransac_ms", r.ransac_ms}});
  if (r.attempted) t->ransac_ms.push_back(r.ransac_ms);
  const double rot = r.rotation_deg, trans = r.translation;
  if (!r.success) {
    std::string reason = r.failure.empty() ? std::string("no pose") : r.failure;
    // The reason's kind, without its numbers.
    reason = reason.substr(0, reason.find_first_of("0123456789"));
    ++(*failures)[reason];
    return;
  }
  ++t->successes;
  t->localized += rot <= dm.max_rotation_deg && trans <= dm.max_translation;
  if (rot > o.wrong_rotation_deg || trans > o.wrong_translation) {
    ++t->wrong;
    wrong->push_back({{"dataset", dataset},
                      {"key", key},
                      {"query", query},
                      {"method", method},
                      {"rotation_deg", rot},
                      {"translation", trans},
                      {"inliers", r.inliers},
                      {"sigma_px", r.sigma_px.value_or(0.0)},
                      {"iterations", r.iterations},
                      {"stop_reason", r.stop_reason}});
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

ojson RunKeySweep(const KeySweepOptions& options) {
  options.Check();
  DirectMatchingOptions dm;
  dm.methods = options.methods;
  dm.rig_methods = options.rig_methods;
  dm.image.sift.extractor = options.features;
  std::map<std::string, MethodTally> tallies;
  std::map<std::string, int> failures;
  ojson wrong = ojson::array(), datasets = ojson::array(), queries = ojson::array();
  for (const std::string& work_dir : options.work_dirs) {
    const EvalWork work = ReadPreparedWork(work_dir);
    datasets.push_back(work.dataset);
    dm.extracted = std::make_shared<ExtractedPhotos>();  // each photo extracted once
    for (uint64_t k = options.first_key; k < options.first_key + options.keys; ++k) {
      const auto start = std::chrono::steady_clock::now();
      const DirectMatchingReport report = RunDirectMatching(work, work_dir, SweepKey(k), dm);
      for (const DirectMatchingPhoto& row : report.per_query) {
        for (const std::string& m : dm.methods) {
          Count(options, dm, work.dataset, k, row.image, m, row.methods.at(m), &tallies[m], &wrong,
                &queries, &failures);
        }
      }
      for (const DirectMatchingRig& row : report.per_rig) {
        for (const std::string& m : dm.rig_methods) {
          if (const DirectMatchingAttempt* a = FindIn(row.methods, m))
            Count(options, dm, work.dataset, k, row.group, m, *a, &tallies[m], &wrong, &queries,
                  &failures);
        }
      }
      int wrong_so_far = 0;
      for (const auto& [name, t] : tallies) wrong_so_far += t.wrong;
      LogProgress("[keys] {} key {}: {:.1f} s, {} wrong successes so far", work.dataset, k,
                  std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
                  wrong_so_far);
    }
  }
  ojson methods = ojson::object();
  for (const auto& [name, t] : tallies) {
    double sum = 0;
    for (const double ms : t.ransac_ms) sum += ms;
    methods[name] = {{"queries", t.queries},
                     {"successes", t.successes},
                     {"localized", t.localized},
                     {"wrong", t.wrong},
                     {"ransac_ms",
                      {{"mean", t.ransac_ms.empty() ? 0.0 : sum / t.ransac_ms.size()},
                       {"p50", Percentile(t.ransac_ms, 50)},
                       {"p99", Percentile(t.ransac_ms, 99)}}}};
  }
  ojson report;
  report["datasets"] = datasets;
  report["keys"] = {{"count", options.keys}, {"first", options.first_key}};
  report["features"] = SiftExtractorName(options.features);
  report["thresholds"] = {
      {"wrong",
       {{"rotation_deg", options.wrong_rotation_deg}, {"translation", options.wrong_translation}}},
      {"localized", {{"rotation_deg", dm.max_rotation_deg}, {"translation", dm.max_translation}}}};
  report["methods"] = methods;
  report["wrong"] = wrong;
  report["failures"] = failures;
  report["queries"] = queries;
  WriteFileAtomically(options.out, [&](std::ostream& os) { os << report.dump(2) << "\n"; });
  return report;
}

}  // namespace linecloud
