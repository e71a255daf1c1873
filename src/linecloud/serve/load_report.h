// What `linecloud bench serve` (load.h) measures, as a type: ToJson gives
// `--json`'s layout, LoadMarkdown the tables of docs/serve.md.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace linecloud {

// One level: `concurrency` keep-alive clients sending one kind of body.
struct LoadLevel {
  std::string body;  // "features", "photo", "rig of 4 photos", ...
  int concurrency = 0;
  size_t requests = 0;
  double per_second = 0, p50_ms = 0, p99_ms = 0;
  std::map<int, int> statuses;  // HTTP status -> answers; 0: no answer
  int poses = 0;                // 200 answers with a pose
};

// Resident memory before and after many more requests (a leak shows as growth).
struct LeakCheck {
  size_t requests = 0;
  double rss_before_mb = 0, rss_after_mb = 0;
  std::map<int, int> statuses;
};

// One client alone, then under attack (hostile requests and dribbled headers).
struct AttackSoak {
  double seconds = 0;
  int attackers = 0, dribblers = 0;
  LoadLevel alone, under_attack;
  double p99_ratio = 0;  // under attack / alone
  size_t hostile_requests = 0;
  std::map<std::string, std::map<int, int>> hostile_statuses;  // by kind of request
  double rss_before_mb = 0, rss_after_mb = 0;
};

struct LoadReport {
  std::string map;
  size_t client_features = 0;
  int workers = 0, queue = 0;
  unsigned hardware_threads = 0;
  std::optional<size_t> rig_frames;
  std::vector<LoadLevel> levels;
  std::optional<LeakCheck> leak_check;
  std::optional<AttackSoak> attack;
};

nlohmann::json ToJson(const LoadReport& report);
std::string LoadMarkdown(const LoadReport& report);

}  // namespace linecloud
