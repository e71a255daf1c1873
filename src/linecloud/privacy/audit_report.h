// What `linecloud audit` finds, as a type: report.json's content (ToJson),
// read back with errors naming the field (AuditReportFromJson, as the
// service does with a map's audit file) and rendered as report.md
// (AuditMarkdown). The computation is audit.h.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "linecloud/privacy/recovery_score.h"

namespace linecloud {

// RecoveryScore's figures without the per-point errors.
struct RecoverySummary {
  size_t points = 0;
  double diagonal = 0;      // model units
  double median_error = 0;  // model units
  double median_error_diagonal_percent = 0;
  // (threshold, share of the points within it): percent of the diagonal, and metres when metric.
  std::vector<std::pair<double, double>> within_diagonal_percent;
  std::optional<double> metric_scale;  // metres per model unit
  std::optional<double> median_error_m;
  std::vector<std::pair<double, double>> within_m;
};

RecoverySummary SummarizeRecovery(const RecoveryScore& score);

// The density attack (Chelani, Kahl, Sattler, CVPR 2021) on the map.
struct DensityAttackReport {
  std::string method;
  int line_neighbours = 0, refine_rounds = 0, refine_neighbours = 0;
  size_t lines_without_votes = 0;
  // How neighbours were found: "every pair", or "grid" (density_attack.h)
  // with its line-to-line radius (model units) and the lines that found
  // fewer than line_neighbours within it.
  std::string search = "every pair";
  std::optional<double> search_radius;
  size_t lines_short_of_neighbours = 0;
  double seconds = 0;
  RecoverySummary recovery;
  std::string why_nothing;  // empty unless nothing could be recovered
};

// The two-liftings attack (Speciale et al., CVPR 2019, Sec. 3.1) with a second map.
struct TwoKeyReport {
  std::string other_map, pairing;
  size_t pairs = 0, parallel_pairs = 0, recovered = 0, recovered_exactly = 0;
  double share_recovered_exactly = 0;
  std::string exact_means;
  std::string why_nothing;  // empty unless nothing was recovered exactly
};

// One way of pairing lines, intersected and scored against the secret points.
struct PairingReport {
  std::string pairing;
  size_t pairs = 0, parallel_pairs = 0, intersections = 0, recovered = 0;
  double share_recovered = 0, seconds = 0;
  // With a second map: what this pairing recovers beyond the map's own crossings.
  std::optional<size_t> recovered_beyond_own;
  std::optional<double> share_recovered_beyond_own;
  // With the density attack run: what this pairing recovers that it does not.
  std::optional<size_t> recovered_beyond_density;
  std::optional<double> share_recovered_beyond_density;
  // Beyond both the map's own crossings and the density attack: what the
  // second map adds to what this map gives by itself.
  std::optional<size_t> recovered_beyond_map;
  std::optional<double> share_recovered_beyond_map;
};

// The second map brought into this map's frame from the two files alone
// (map_alignment.h), as an attacker would before pairing.
struct MapAlignmentReport {
  bool aligned = false;
  std::string why_not;  // empty when aligned
  size_t descriptor_pairs = 0, ransac_inliers = 0, refined_pairs = 0;
  double median_line_distance_diagonal = 0;  // refined pairs' lines, share of the diagonal
  double scale = 1, rotation_deg = 0;        // of this map from the other
};

struct PairingAttacksReport {
  double crossing_tolerance_diagonal = 0, recovered_within_diagonal = 0;
  PairingReport self_crossings;
  std::optional<PairingReport> by_id, by_descriptor, by_crossing;  // with a second map
  std::optional<size_t> most_recovered_beyond_own;
  std::optional<double> share_most_recovered_beyond_own;
  // The second map aligned first; then one estimate per line of this map: its
  // line paired with the other map's line of nearest descriptor, or with the
  // other map's nearest line (within the crossing tolerance), intersected.
  std::optional<MapAlignmentReport> alignment;
  std::optional<PairingReport> aligned_by_descriptor, aligned_by_nearest_line;
  // The attacker's best of those two; beyond the map alone: not already
  // recovered by its own crossings, nor by the density attack when the audit
  // ran it.
  std::optional<size_t> most_recovered_aligned, most_recovered_aligned_beyond_map;
  std::optional<double> share_most_recovered_aligned, share_most_recovered_aligned_beyond_map;
};

struct AuditReport {
  std::string map, model, encoding;
  size_t lines = 0, model_points = 0;
  double diagonal = 0;                 // model units
  std::optional<double> metric_scale;  // metres per model unit
  std::optional<DensityAttackReport> density_attack;
  std::optional<TwoKeyReport> two_keys;
  PairingAttacksReport pairing_attacks;
};

nlohmann::ordered_json ToJson(const AuditReport& report);
// Errors name `where` and the field's path; shares must lie in [0, 1], counts
// be integers >= 0, and no count exceed the map's lines.
AuditReport AuditReportFromJson(const nlohmann::json& j, const std::string& where);

// report.md.
std::string AuditMarkdown(const AuditReport& report);

// A share as report.md and audit.png show it: "12.3 %".
std::string SharePercent(double share);

}  // namespace linecloud
