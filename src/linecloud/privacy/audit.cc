#include "linecloud/privacy/audit.h"

#include <algorithm>
#include <chrono>
#ifdef __GLIBC__
#include <malloc.h>
#endif
#include <cmath>
#include <optional>
#include <filesystem>
#include <unordered_map>

#include <fmt/format.h>
#include <Eigen/Geometry>

#include "linecloud/geometry/line_grid.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/io/lift_model.h"
#include "linecloud/io/ply.h"
#include "linecloud/lifting/identity.h"
#include "linecloud/lifting/lifting.h"
#include "linecloud/draw/audit_figure.h"
#include "linecloud/privacy/map_alignment.h"
#include "linecloud/privacy/recovery_score.h"
#include "linecloud/privacy/two_key_attack.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

// recovered.ply's colours: audit.png's (audit_figure.h), as bytes.
std::vector<std::array<uint8_t, 3>> ErrorColours(const RecoveryScore& s) {
  std::vector<std::array<uint8_t, 3>> colours;
  for (const double e : s.errors) {
    const std::array<double, 3> c = ErrorColour(e, s.diagonal);
    colours.push_back({static_cast<uint8_t>(std::lround(255 * c[0])),
                       static_cast<uint8_t>(std::lround(255 * c[1])),
                       static_cast<uint8_t>(std::lround(255 * c[2]))});
  }
  return colours;
}

DensityAttackReport DensityAttackOf(const DensityAttackResult& r, const DensityAttackOptions& o,
                                    const RecoveryScore& score) {
  DensityAttackReport a;
  a.method = "Chelani, Kahl, Sattler, CVPR 2021 (density of the line cloud)";
  a.line_neighbours = r.line_neighbours;
  a.refine_rounds = o.refine_rounds;
  a.refine_neighbours = o.refine_neighbours;
  a.lines_without_votes = r.lines_without_votes;
  if (r.search_radius > 0) {
    a.search = "grid";
    a.search_radius = r.search_radius;
    a.lines_short_of_neighbours = r.lines_short_of_neighbours;
  }
  a.seconds = r.seconds;
  a.recovery = SummarizeRecovery(score);
  if (r.lines_without_votes == r.points.size()) {
    a.why_nothing =
        "no two lines of the map cross at an angle (all parallel): no line has a "
        "vote, and every estimate is the line's anchor";
  }
  return a;
}

TwoKeyReport TwoKeyOf(const TwoLiftingsAttack& attack, const std::vector<Eigen::Vector3d>& secret,
                      double diagonal, size_t lines, const std::string& other) {
  TwoKeyReport t;
  for (size_t k = 0; k < attack.points.size(); ++k) {
    t.recovered_exactly += (attack.points[k] - secret[attack.indices[k]]).norm() <= 1e-6 * diagonal;
  }
  t.other_map = other;
  t.pairing = attack.pairing;
  t.pairs = attack.shared_ids;
  t.parallel_pairs = attack.parallel;
  t.recovered = attack.points.size();
  t.share_recovered_exactly = lines ? static_cast<double>(t.recovered_exactly) / lines : 0.0;
  t.exact_means = "within 1e-6 of the scene diagonal";
  if (t.recovered_exactly == 0) {
    t.why_nothing =
        "no line of the other map crosses a line of this map in one of its points: "
        "the maps hold no common point (another scene, or a disjoint part of it)";
  }
  return t;
}

// The points of `a` (the audited map) an attack recovers: those with an
// intersection within `within` of their secret point.
std::vector<uint8_t> Recovered(const TwoLiftingsAttack& attack,
                               const std::vector<Eigen::Vector3d>& secret, double within) {
  std::vector<uint8_t> recovered(secret.size(), 0);
  for (size_t k = 0; k < attack.points.size(); ++k) {
    const size_t i = attack.indices[k];
    if ((attack.points[k] - secret[i]).norm() <= within) recovered[i] = 1;
  }
  return recovered;
}

// A pairing's report from the points it recovered. `own`: the points the
// map's own crossings recover; a pairing of two maps is then also scored by
// what it recovers beyond them (what the second map adds).
PairingReport ScoredPairing(const TwoLiftingsAttack& attack, size_t intersections,
                            const std::vector<uint8_t>& recovered, double seconds,
                            const std::vector<uint8_t>* own = nullptr,
                            const std::vector<uint8_t>* density = nullptr) {
  const double points = static_cast<double>(recovered.size());
  const auto beyond = [&](const std::vector<uint8_t>* a, const std::vector<uint8_t>* b) {
    size_t count = 0;
    for (size_t i = 0; i < recovered.size(); ++i) {
      count += recovered[i] && !(a && (*a)[i]) && !(b && (*b)[i]);
    }
    return count;
  };
  PairingReport p;
  p.pairing = attack.pairing;
  p.pairs = attack.shared_ids;
  p.parallel_pairs = attack.parallel;
  p.intersections = intersections;
  p.recovered = static_cast<size_t>(std::count(recovered.begin(), recovered.end(), 1));
  p.share_recovered = recovered.empty() ? 0.0 : p.recovered / points;
  p.seconds = seconds;
  if (own) {
    p.recovered_beyond_own = beyond(own, nullptr);
    p.share_recovered_beyond_own = recovered.empty() ? 0.0 : *p.recovered_beyond_own / points;
  }
  if (density) {
    p.recovered_beyond_density = beyond(density, nullptr);
    p.share_recovered_beyond_density =
        recovered.empty() ? 0.0 : *p.recovered_beyond_density / points;
  }
  if (density && own) {
    p.recovered_beyond_map = beyond(density, own);
    p.share_recovered_beyond_map = recovered.empty() ? 0.0 : *p.recovered_beyond_map / points;
  }
  return p;
}

PairingReport PairingOf(const TwoLiftingsAttack& attack, const std::vector<Eigen::Vector3d>& secret,
                        double within, double seconds, std::vector<uint8_t>* recovered,
                        const std::vector<uint8_t>* own = nullptr,
                        const std::vector<uint8_t>* density = nullptr) {
  *recovered = Recovered(attack, secret, within);
  return ScoredPairing(attack, attack.points.size(), *recovered, seconds, own, density);
}

// A map's own lines that cross (two points at one place, different
// directions), streamed: the points whose secret lies within `within` of a
// crossing of their line.
PairingReport SelfCrossingsOf(const LineCloud& cloud, const Eigen::AlignedBox3d& box,
                              double tolerance, const std::vector<Eigen::Vector3d>& secret,
                              double within, int threads, std::vector<uint8_t>* own) {
  const auto start = std::chrono::steady_clock::now();
  own->assign(secret.size(), 0);
  TwoLiftingsAttack self;
  self.pairing = "crossing lines of one map";
  self.shared_ids = ForEachSelfCrossing(
      cloud, box, tolerance,
      [&](uint32_t i, uint32_t j, const Eigen::Vector3d& mid) {
        if ((mid - secret[i]).norm() <= within) (*own)[i] = 1;
        if ((mid - secret[j]).norm() <= within) (*own)[j] = 1;
      },
      1e-6, threads);
  return ScoredPairing(
      self, self.shared_ids, *own,
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
}

MapAlignmentReport AlignmentOf(const MapAlignment& a) {
  MapAlignmentReport r;
  r.aligned = a.aligned;
  r.why_not = a.why_not;
  r.descriptor_pairs = a.descriptor_pairs;
  r.ransac_inliers = a.ransac_inliers;
  r.refined_pairs = a.refined_pairs;
  r.median_line_distance_diagonal = a.median_line_distance;
  r.scale = a.a_from_b.scale;
  r.rotation_deg = Eigen::AngleAxisd(a.a_from_b.rotation).angle() * 180 / M_PI;
  return r;
}

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The other map aligned first from the two files (map_alignment.h), then one
// estimate per line of `cloud`: the attacker's best pairings. `density`: the
// density attack on `cloud` when the audit ran it (scored beyond it), else
// null. The alignment needs only rough estimates: the attack's first step.
void AlignedPairingsOf(const LineCloud& cloud, const LineCloud& other,
                       const DensityAttackResult* density,
                       const std::vector<Eigen::Vector3d>& secret, double within,
                       const std::vector<uint8_t>& own, const AuditOptions& o,
                       PairingAttacksReport* p) {
  DensityAttackOptions rough = o.attack;
  rough.refine_rounds = 0;
  const DensityAttackResult cloud_rough =
      density ? DensityAttackResult() : RunDensityAttack(cloud, rough);
  const DensityAttackResult& estimates = density ? *density : cloud_rough;
  std::vector<uint8_t> by_density(secret.size(), 0);
  for (size_t i = 0; density && i < secret.size(); ++i) {
    by_density[i] = (density->points[i] - secret[i]).norm() <= within;
  }
  const MapAlignment alignment =
      AlignMaps(cloud, other, estimates, RunDensityAttack(other, rough), {});
  p->alignment = AlignmentOf(alignment);
  if (!alignment.aligned) return;
  const LineCloud moved = TransformedCloud(other, alignment.a_from_b);
  std::vector<uint8_t> recovered;
  const auto add = [&](const TwoLiftingsAttack& attack, double seconds, const char* name) {
    PairingReport r = PairingOf(attack, secret, within, seconds, &recovered, &own,
                                density ? &by_density : nullptr);
    r.pairing = fmt::format("{}, after alignment", name);
    return r;
  };
  auto start = std::chrono::steady_clock::now();
  const TwoLiftingsAttack by_descriptor = IntersectLinesOfNearestDescriptor(cloud, moved);
  p->aligned_by_descriptor = add(by_descriptor, SecondsSince(start), "nearest descriptor");
  start = std::chrono::steady_clock::now();
  const TwoLiftingsAttack by_line =
      IntersectCrossingLines(cloud, moved, o.crossing_tolerance, o.attack.threads);
  p->aligned_by_nearest_line = add(by_line, SecondsSince(start), "nearest line");
  size_t most = 0, most_beyond = 0;
  for (const auto* a : {&p->aligned_by_descriptor, &p->aligned_by_nearest_line}) {
    most = std::max(most, (*a)->recovered);
    most_beyond =
        std::max(most_beyond, (*a)->recovered_beyond_map.value_or(*(*a)->recovered_beyond_own));
  }
  const double points = static_cast<double>(std::max<size_t>(secret.size(), 1));
  p->most_recovered_aligned = most;
  p->share_most_recovered_aligned = most / points;
  p->most_recovered_aligned_beyond_map = most_beyond;
  p->share_most_recovered_aligned_beyond_map = most_beyond / points;
}

// What one map's own lines give away (points at one place lifted with
// different directions cross there), and with `other` (another version or
// lifting of the model) what pairing the two maps by equal id, by nearest
// descriptor and by crossing lines recovers.
// Then the other map aligned as an attacker would (AlignedPairingsOf).
PairingAttacksReport PairingAttacksOf(const LineCloud& cloud, const LineCloud* other,
                                      const std::vector<Eigen::Vector3d>& secret, double diagonal,
                                      const DensityAttackResult* density, const AuditOptions& o) {
  const Eigen::AlignedBox3d box = RobustBox(secret, 0.005, 0.05);
  const double tolerance = o.crossing_tolerance * diagonal;
  const double within = o.recovered_within * diagonal;
  PairingAttacksReport p;
  p.crossing_tolerance_diagonal = o.crossing_tolerance;
  p.recovered_within_diagonal = o.recovered_within;
  auto start = std::chrono::steady_clock::now();
  std::vector<uint8_t> own, recovered;
  p.self_crossings = SelfCrossingsOf(cloud, box, tolerance, secret, within, o.attack.threads, &own);
  if (!other) return p;
  start = std::chrono::steady_clock::now();
  // Each attack runs before its time is read (arguments have no order).
  const TwoLiftingsAttack by_id = IntersectLinesOfEqualId(cloud, *other);
  p.by_id = PairingOf(by_id, secret, within, SecondsSince(start), &recovered, &own);
  if (cloud.has_descriptors() && other->has_descriptors() &&
      cloud.descriptor_dim == other->descriptor_dim) {
    start = std::chrono::steady_clock::now();
    const TwoLiftingsAttack by_descriptor = IntersectLinesOfNearestDescriptor(cloud, *other);
    p.by_descriptor =
        PairingOf(by_descriptor, secret, within, SecondsSince(start), &recovered, &own);
  }
  start = std::chrono::steady_clock::now();
  const TwoLiftingsAttack by_crossing =
      IntersectCrossingLinesInBox(cloud, *other, box, tolerance, 1e-6, o.attack.threads);
  p.by_crossing = PairingOf(by_crossing, secret, within, SecondsSince(start), &recovered, &own);
  // What the second map adds: the most any pairing recovers beyond the map's
  // own crossings.
  size_t worst = 0;
  for (const auto* a : {&p.by_id, &p.by_descriptor, &p.by_crossing}) {
    if (*a) worst = std::max(worst, *(*a)->recovered_beyond_own);
  }
  p.most_recovered_beyond_own = worst;
  p.share_most_recovered_beyond_own =
      secret.empty() ? 0.0 : static_cast<double>(worst) / secret.size();
  if (cloud.has_descriptors() && other->has_descriptors()) {
    AlignedPairingsOf(cloud, *other, density, secret, within, own, o, &p);
  }
  return p;
}

}  // namespace

void AuditOptions::Check() const {
  if (map_path.empty()) Fail("audit: --map is required");
  if (model_dir.empty())
    Fail("audit: --model (the secret model the map was lifted from) is required");
  if (!(metric_scale >= 0) || !std::isfinite(metric_scale)) {
    Fail("--metric-scale: {} is not a finite non-negative number", metric_scale);
  }
  if (skip_density_attack && other_map_path.empty()) {
    Fail("audit: nothing to do (--no-density-attack without --other)");
  }
  attack.Check();
  if (!(crossing_tolerance > 0 && crossing_tolerance < 0.1)) {
    Fail("--crossing-tolerance: {} is not a share of the diagonal in (0, 0.1)", crossing_tolerance);
  }
  if (!(recovered_within > 0 && recovered_within < 0.1)) {
    Fail("--recovered-within: {} is not a share of the diagonal in (0, 0.1)", recovered_within);
  }
}

std::vector<Eigen::Vector3d> SecretPointsOfLines(const LineCloud& cloud,
                                                 const Reconstruction& model, const LiftingKey& key,
                                                 const std::string& map_name) {
  if (cloud.key_fingerprint != key.Fingerprint()) {
    Fail(
        "{}: lifted with another key than the model's (fingerprint {} vs {}): the map and the "
        "model do not belong together",
        map_name, ToHex(cloud.key_fingerprint), ToHex(key.Fingerprint()));
  }
  const std::vector<uint64_t> point_ids =
      cloud.keyed_line_ids ? PointIdsOfLines(key, cloud.ids) : cloud.ids;
  std::vector<Eigen::Vector3d> secret;
  secret.reserve(point_ids.size());
  size_t missing = 0;
  for (const uint64_t id : point_ids) {
    const auto it = model.points3D.find(id);
    if (it == model.points3D.end()) {
      ++missing;
      continue;
    }
    secret.push_back(it->second.xyz);
  }
  if (missing > 0) {
    Fail(
        "{}: {} of its {} lines name no point of the model: the map was lifted from another "
        "model (or another version of it)",
        map_name, missing, point_ids.size());
  }
  // A line must pass through its point, or the map is not this model's (a
  // version's line may be its released line, within kMaxSnap of the point).
  const double released = 2 * kMaxSnap * SceneDiagonal(secret);
  for (size_t i = 0; i < secret.size(); ++i) {
    const PluckerLine& l = cloud.lines[i];
    const double d = (secret[i].cross(l.v) - l.w).norm() / l.v.norm();
    if (!(d <= 1e-3 * (1 + secret[i].norm()) + released)) {
      Fail(
          "{}: line {} does not pass through its model point (off by {:.3g}): the map was "
          "lifted from another model",
          map_name, i, d);
    }
  }
  return secret;
}

AuditReport RunAudit(const AuditOptions& o) {
  o.Check();
  return RunAudit(ReadLineCloud(o.map_path), o);
}

AuditReport RunAudit(const LineCloud& cloud, const AuditOptions& o) {
  o.Check();
  // Only the secret points are kept from the model (a model of a million
  // points with its images' observations is larger than the attacks' needs).
  size_t model_points = 0;
  const std::vector<Eigen::Vector3d> secret = [&] {
    const Reconstruction model = ReadColmapModel(o.model_dir);
    model_points = model.points3D.size();
    // The public demo key needs no key store (anyone can compute it).
    const LiftingKey key =
        o.key_file.empty() && cloud.key_fingerprint == DemoLiftingKey().Fingerprint()
            ? DemoLiftingKey()
            : ModelKey(model, o.model_dir, o.key_file, o.key_store);
    return SecretPointsOfLines(cloud, model, key, o.map_path);
  }();
#ifdef __GLIBC__
  malloc_trim(0);  // the model's many small blocks back to the system
#endif
  if (secret.empty()) Fail("{}: the map has no lines", o.map_path);
  const double diagonal = SceneDiagonal(secret);

  AuditReport report;
  report.map = o.map_path;
  report.model = o.model_dir;
  report.lines = cloud.size();
  report.model_points = model_points;
  report.encoding = LineEncodingName(cloud.encoding);
  report.diagonal = diagonal;
  if (o.metric_scale > 0) report.metric_scale = o.metric_scale;
  std::optional<DensityAttackResult> density;
  if (!o.skip_density_attack) {
    density = RunDensityAttack(cloud, o.attack);
    const DensityAttackResult& attack = *density;
    const RecoveryScore score = ScoreRecovery(attack.points, secret, o.metric_scale);
    report.density_attack = DensityAttackOf(attack, o.attack, score);
    if (!o.out_dir.empty()) {
      CreateDirectories(o.out_dir);
      WritePointsPly(JoinPaths(o.out_dir, "recovered.ply"), attack.points, ErrorColours(score),
                     "linecloud audit: points recovered by the density attack, coloured by error "
                     "(sky blue 0, yellow 1 %, vermilion >= 2 % of the scene diagonal)",
                     0600);  // the secret the map protects: the owner's only
      WriteAuditFigure(
          JoinPaths(o.out_dir, "audit.png"), secret, attack.points, score.errors, diagonal,
          {fmt::format("What an attacker recovers from {} ({} lines)",
                       std::filesystem::path(o.map_path).filename().string(), cloud.size()),
           fmt::format("density attack: {} of the points within 1 % of the scene diagonal, {} "
                       "within 0.5 %; median error {:.2f} % of the diagonal",
                       SharePercent(ShareWithinDiagonal(score, 1.0)),
                       SharePercent(ShareWithinDiagonal(score, 0.5)),
                       100 * score.median_error / diagonal)});
    }
  }
  std::optional<LineCloud> other;
  if (!o.other_map_path.empty()) {
    other = ReadLineCloud(o.other_map_path);
    const TwoLiftingsAttack attack = AttackTwoLiftings(cloud, *other, o.attack.threads);
    report.two_keys = TwoKeyOf(attack, secret, diagonal, cloud.size(), o.other_map_path);
  }
  report.pairing_attacks = PairingAttacksOf(cloud, other ? &*other : nullptr, secret, diagonal,
                                            density ? &*density : nullptr, o);
  if (!o.out_dir.empty()) {
    CreateDirectories(o.out_dir);
    WriteFileAtomically(JoinPaths(o.out_dir, "report.json"),
                        [&](std::ostream& out) { out << ToJson(report).dump(2) << "\n"; });
    WriteFileAtomically(JoinPaths(o.out_dir, "report.md"),
                        [&](std::ostream& out) { out << AuditMarkdown(report); });
  }
  return report;
}

}  // namespace linecloud
