#include "linecloud/privacy/audit_report.h"

#include <cmath>
#include <cstdlib>

#include <fmt/format.h>

#include "linecloud/io/json_util.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using ojson = nlohmann::ordered_json;

ojson NumberOrNull(const std::optional<double>& v) { return v ? ojson(*v) : ojson(nullptr); }

// {"0.5": share, "1": share, ...}: a threshold's share of the points.
ojson SharesJson(const std::vector<std::pair<double, double>>& shares) {
  ojson j = ojson::object();
  for (const auto& [threshold, share] : shares) j[fmt::format("{}", threshold)] = share;
  return j;
}

std::vector<std::pair<double, double>> SharesFrom(const JsonFields& f, const char* key) {
  const JsonFields shares = f.Object(key);
  std::vector<std::pair<double, double>> out;
  for (const auto& [name, value] : shares.raw().items()) {
    char* end = nullptr;
    const double threshold = std::strtod(name.c_str(), &end);
    if (name.empty() || *end != '\0' || !(threshold > 0) || !std::isfinite(threshold)) {
      Fail("{}: {} is not a positive threshold", shares.Where(name),
           ShownInMessage(nlohmann::json(name)));
    }
    out.push_back({threshold, shares.Share(name.c_str())});
  }
  return out;
}

std::optional<double> OptionalNonNegative(const JsonFields& f, const char* key) {
  if (!f.Has(key) || f.At(key).is_null()) return std::nullopt;
  return f.NonNegative(key);
}

ojson ToJson(const RecoverySummary& s) {
  ojson j = {{"points", s.points},
             {"diagonal", s.diagonal},
             {"median_error", s.median_error},
             {"median_error_diagonal_percent", s.median_error_diagonal_percent},
             {"within_diagonal_percent", SharesJson(s.within_diagonal_percent)},
             {"metric_scale", NumberOrNull(s.metric_scale)}};
  if (s.metric_scale) {
    j["median_error_m"] = NumberOrNull(s.median_error_m);
    j["within_m"] = SharesJson(s.within_m);
  }
  return j;
}

RecoverySummary RecoveryFrom(const JsonFields& f) {
  RecoverySummary s;
  s.points = f.Count("points");
  s.diagonal = f.NonNegative("diagonal");
  s.median_error = f.NonNegative("median_error");
  s.median_error_diagonal_percent = f.NonNegative("median_error_diagonal_percent");
  s.within_diagonal_percent = SharesFrom(f, "within_diagonal_percent");
  s.metric_scale = OptionalNonNegative(f, "metric_scale");
  if (s.metric_scale) {
    s.median_error_m = OptionalNonNegative(f, "median_error_m");
    s.within_m = SharesFrom(f, "within_m");
  }
  return s;
}

ojson ToJson(const DensityAttackReport& a) {
  ojson j = {{"method", a.method},
             {"line_neighbours", a.line_neighbours},
             {"refine_rounds", a.refine_rounds},
             {"refine_neighbours", a.refine_neighbours},
             {"lines_without_votes", a.lines_without_votes},
             {"search", a.search},
             {"search_radius", a.search_radius ? ojson(*a.search_radius) : ojson(nullptr)},
             {"lines_short_of_neighbours", a.lines_short_of_neighbours},
             {"seconds", a.seconds},
             {"recovery", ToJson(a.recovery)}};
  if (!a.why_nothing.empty()) j["why_nothing"] = a.why_nothing;
  return j;
}

DensityAttackReport DensityAttackFrom(const JsonFields& f) {
  DensityAttackReport a;
  a.method = f.String("method");
  a.line_neighbours = f.Int("line_neighbours");
  a.refine_rounds = f.Int("refine_rounds");
  a.refine_neighbours = f.Int("refine_neighbours");
  a.lines_without_votes = f.Count("lines_without_votes");
  // Reports written before the grid search have no search fields: every pair.
  a.search = f.StringOr("search", "every pair");
  if (a.search != "every pair" && a.search != "grid") {
    Fail("{}: \"{}\" is not a search (every pair, grid)", f.Where("search"), a.search);
  }
  a.search_radius = OptionalNonNegative(f, "search_radius");
  if (f.Has("lines_short_of_neighbours")) {
    a.lines_short_of_neighbours = f.Count("lines_short_of_neighbours");
  }
  a.seconds = f.NonNegative("seconds");
  a.recovery = RecoveryFrom(f.Object("recovery"));
  a.why_nothing = f.StringOr("why_nothing", "");
  return a;
}

ojson ToJson(const TwoKeyReport& t) {
  ojson j = {{"other_map", t.other_map},
             {"pairing", t.pairing},
             {"pairs", t.pairs},
             {"parallel_pairs", t.parallel_pairs},
             {"recovered", t.recovered},
             {"recovered_exactly", t.recovered_exactly},
             {"share_recovered_exactly", t.share_recovered_exactly},
             {"exact_means", t.exact_means}};
  if (!t.why_nothing.empty()) j["why_nothing"] = t.why_nothing;
  return j;
}

TwoKeyReport TwoKeyFrom(const JsonFields& f) {
  TwoKeyReport t;
  t.other_map = f.String("other_map");
  t.pairing = f.String("pairing");
  t.pairs = f.Count("pairs");
  t.parallel_pairs = f.Count("parallel_pairs");
  t.recovered = f.Count("recovered");
  t.recovered_exactly = f.Count("recovered_exactly");
  t.share_recovered_exactly = f.Share("share_recovered_exactly");
  t.exact_means = f.String("exact_means");
  t.why_nothing = f.StringOr("why_nothing", "");
  if (t.recovered_exactly > t.recovered) {
    Fail("{}: {} recovered exactly of {} recovered", f.Where("recovered_exactly"),
         t.recovered_exactly, t.recovered);
  }
  return t;
}

ojson ToJson(const PairingReport& p) {
  ojson j = {{"pairing", p.pairing},
             {"pairs", p.pairs},
             {"parallel_pairs", p.parallel_pairs},
             {"intersections", p.intersections},
             {"recovered", p.recovered},
             {"share_recovered", p.share_recovered},
             {"seconds", p.seconds}};
  if (p.recovered_beyond_own) j["recovered_beyond_own"] = *p.recovered_beyond_own;
  if (p.share_recovered_beyond_own) j["share_recovered_beyond_own"] = *p.share_recovered_beyond_own;
  if (p.recovered_beyond_density) j["recovered_beyond_density"] = *p.recovered_beyond_density;
  if (p.share_recovered_beyond_density)
    j["share_recovered_beyond_density"] = *p.share_recovered_beyond_density;
  if (p.recovered_beyond_map) j["recovered_beyond_map"] = *p.recovered_beyond_map;
  if (p.share_recovered_beyond_map) j["share_recovered_beyond_map"] = *p.share_recovered_beyond_map;
  return j;
}

PairingReport PairingFrom(const JsonFields& f, size_t lines) {
  PairingReport p;
  p.pairing = f.String("pairing");
  p.pairs = f.Count("pairs");
  p.parallel_pairs = f.Count("parallel_pairs");
  p.intersections = f.Count("intersections");
  p.recovered = f.Count("recovered");
  p.share_recovered = f.Share("share_recovered");
  p.seconds = f.NonNegative("seconds");
  if (f.Has("recovered_beyond_own")) p.recovered_beyond_own = f.Count("recovered_beyond_own");
  if (f.Has("share_recovered_beyond_own"))
    p.share_recovered_beyond_own = f.Share("share_recovered_beyond_own");
  if (f.Has("recovered_beyond_density"))
    p.recovered_beyond_density = f.Count("recovered_beyond_density");
  if (f.Has("share_recovered_beyond_density"))
    p.share_recovered_beyond_density = f.Share("share_recovered_beyond_density");
  if (f.Has("recovered_beyond_map")) p.recovered_beyond_map = f.Count("recovered_beyond_map");
  if (f.Has("share_recovered_beyond_map"))
    p.share_recovered_beyond_map = f.Share("share_recovered_beyond_map");
  if (p.recovered > lines) {
    Fail("{}: {} points recovered from a map of {} lines", f.Where("recovered"), p.recovered,
         lines);
  }
  return p;
}

ojson ToJson(const MapAlignmentReport& a) {
  ojson j = {{"aligned", a.aligned},
             {"descriptor_pairs", a.descriptor_pairs},
             {"ransac_inliers", a.ransac_inliers},
             {"refined_pairs", a.refined_pairs},
             {"median_line_distance_diagonal", a.median_line_distance_diagonal},
             {"scale", a.scale},
             {"rotation_deg", a.rotation_deg}};
  if (!a.why_not.empty()) j["why_not"] = a.why_not;
  return j;
}

MapAlignmentReport AlignmentFrom(const JsonFields& f) {
  MapAlignmentReport a;
  a.aligned = f.Bool("aligned");
  a.why_not = f.StringOr("why_not", "");
  a.descriptor_pairs = f.Count("descriptor_pairs");
  a.ransac_inliers = f.Count("ransac_inliers");
  a.refined_pairs = f.Count("refined_pairs");
  a.median_line_distance_diagonal = f.NonNegative("median_line_distance_diagonal");
  a.scale = f.NonNegative("scale");
  a.rotation_deg = f.NonNegative("rotation_deg");
  return a;
}

ojson ToJson(const PairingAttacksReport& p) {
  ojson j = {{"crossing_tolerance_diagonal", p.crossing_tolerance_diagonal},
             {"recovered_within_diagonal", p.recovered_within_diagonal},
             {"self_crossings", ToJson(p.self_crossings)}};
  if (p.by_id) j["by_id"] = ToJson(*p.by_id);
  if (p.by_descriptor) j["by_descriptor"] = ToJson(*p.by_descriptor);
  if (p.by_crossing) j["by_crossing"] = ToJson(*p.by_crossing);
  if (p.most_recovered_beyond_own) j["most_recovered_beyond_own"] = *p.most_recovered_beyond_own;
  if (p.share_most_recovered_beyond_own)
    j["share_most_recovered_beyond_own"] = *p.share_most_recovered_beyond_own;
  if (p.alignment) j["alignment"] = ToJson(*p.alignment);
  if (p.aligned_by_descriptor) j["aligned_by_descriptor"] = ToJson(*p.aligned_by_descriptor);
  if (p.aligned_by_nearest_line) j["aligned_by_nearest_line"] = ToJson(*p.aligned_by_nearest_line);
  if (p.most_recovered_aligned) j["most_recovered_aligned"] = *p.most_recovered_aligned;
  if (p.share_most_recovered_aligned)
    j["share_most_recovered_aligned"] = *p.share_most_recovered_aligned;
  if (p.most_recovered_aligned_beyond_map)
    j["most_recovered_aligned_beyond_map"] = *p.most_recovered_aligned_beyond_map;
  if (p.share_most_recovered_aligned_beyond_map)
    j["share_most_recovered_aligned_beyond_map"] = *p.share_most_recovered_aligned_beyond_map;
  return j;
}

PairingAttacksReport PairingAttacksFrom(const JsonFields& f, size_t lines) {
  PairingAttacksReport p;
  p.crossing_tolerance_diagonal = f.Share("crossing_tolerance_diagonal");
  p.recovered_within_diagonal = f.Share("recovered_within_diagonal");
  p.self_crossings = PairingFrom(f.Object("self_crossings"), lines);
  if (f.Has("by_id")) p.by_id = PairingFrom(f.Object("by_id"), lines);
  if (f.Has("by_descriptor")) p.by_descriptor = PairingFrom(f.Object("by_descriptor"), lines);
  if (f.Has("by_crossing")) p.by_crossing = PairingFrom(f.Object("by_crossing"), lines);
  if (f.Has("most_recovered_beyond_own"))
    p.most_recovered_beyond_own = f.Count("most_recovered_beyond_own");
  if (f.Has("share_most_recovered_beyond_own"))
    p.share_most_recovered_beyond_own = f.Share("share_most_recovered_beyond_own");
  if (f.Has("alignment")) p.alignment = AlignmentFrom(f.Object("alignment"));
  if (f.Has("aligned_by_descriptor"))
    p.aligned_by_descriptor = PairingFrom(f.Object("aligned_by_descriptor"), lines);
  if (f.Has("aligned_by_nearest_line"))
    p.aligned_by_nearest_line = PairingFrom(f.Object("aligned_by_nearest_line"), lines);
  if (f.Has("most_recovered_aligned")) p.most_recovered_aligned = f.Count("most_recovered_aligned");
  if (f.Has("share_most_recovered_aligned"))
    p.share_most_recovered_aligned = f.Share("share_most_recovered_aligned");
  if (f.Has("most_recovered_aligned_beyond_map"))
    p.most_recovered_aligned_beyond_map = f.Count("most_recovered_aligned_beyond_map");
  if (f.Has("share_most_recovered_aligned_beyond_map"))
    p.share_most_recovered_aligned_beyond_map = f.Share("share_most_recovered_aligned_beyond_map");
  return p;
}

// Markdown table cells and headings: what came from a file (a path, a
// pairing's name) must not break the table or start a new line.
std::string Cell(const std::string& text) {
  std::string out;
  for (const char c : text) {
    if (c == '|') {
      out += "\\|";
    } else if (static_cast<unsigned char>(c) < 0x20) {
      out += ' ';
    } else {
      out += c;
    }
  }
  return out;
}

std::string DensityAttackMarkdown(const DensityAttackReport& a) {
  const RecoverySummary& rec = a.recovery;
  std::string md = "## Density attack (Chelani, Kahl, Sattler, CVPR 2021)\n\n";
  md += fmt::format(
      "What anyone holding only the map recovers: for each line, the points where its {} "
      "nearest lines pass closest vote for the hidden point; {} refinement rounds. {:.1f} s.\n\n",
      a.line_neighbours, a.refine_rounds, a.seconds);
  if (a.search_radius) {
    md += fmt::format(
        "Neighbours searched through a grid of the scene (the map is too large to compare every "
        "pair): exact within {:.4g} model units; {} lines found fewer than {} there.\n\n",
        *a.search_radius, a.lines_short_of_neighbours, a.line_neighbours);
  }
  md += "| recovered within | share of the points |\n|---|---|\n";
  for (const auto& [p, share] : rec.within_diagonal_percent) {
    md += fmt::format("| {} % of the diagonal | {} |\n", p, SharePercent(share));
  }
  for (const auto& [m, share] : rec.within_m) {
    md += fmt::format("| {:.0f} cm | {} |\n", 100 * m, SharePercent(share));
  }
  if (!a.why_nothing.empty())
    md += fmt::format("Nothing to vote with: {}.\n\n", Cell(a.why_nothing));
  md += fmt::format(
      "\nMedian error: {:.2f} % of the diagonal{}. `audit.png` shows the secret and "
      "the recovered points side by side; `recovered.ply` the recovered points "
      "coloured by error.\n\n",
      rec.median_error_diagonal_percent,
      rec.median_error_m ? fmt::format(" ({:.3f} m)", *rec.median_error_m) : "");
  return md;
}

std::string TwoKeyMarkdown(const TwoKeyReport& t) {
  std::string md = "## Two liftings of one model (Speciale et al., CVPR 2019, Sec. 3.1)\n\n";
  md += fmt::format(
      "With {} as well, an attacker pairs the lines by {} and intersects them: "
      "{} points recovered, {} of them exactly ({} of the map's points).\n",
      Cell(t.other_map), Cell(t.pairing), t.recovered, t.recovered_exactly,
      SharePercent(t.share_recovered_exactly));
  if (!t.why_nothing.empty()) md += fmt::format("Nothing recovered: {}.\n", Cell(t.why_nothing));
  md += "\nThis is why a model must only ever be lifted with its one key.\n";
  return md;
}

std::string PairingAttacksMarkdown(const PairingAttacksReport& p) {
  std::string md = fmt::format(
      "\n## Pairing attacks\n\nLines paired as an attacker would, intersected; a point counts "
      "as recovered when an intersection lies within {:g} of the scene diagonal of it "
      "(crossings: lines within {:g} of the diagonal of each other). \"Beyond its own\": points "
      "the pairing recovers that the map's own crossings do not (what the other map adds).\n\n"
      "| pairing | pairs | recovered | share | beyond its own |\n|---|---|---|---|---|\n",
      p.recovered_within_diagonal, p.crossing_tolerance_diagonal);
  for (const std::optional<PairingReport>& a :
       {std::optional<PairingReport>(p.self_crossings), p.by_id, p.by_descriptor, p.by_crossing,
        p.aligned_by_descriptor, p.aligned_by_nearest_line}) {
    if (!a) continue;
    md += fmt::format(
        "| {} | {} | {} | {} | {} |\n", Cell(a->pairing), a->pairs, a->recovered,
        SharePercent(a->share_recovered),
        a->share_recovered_beyond_own ? SharePercent(*a->share_recovered_beyond_own) : "—");
  }
  if (p.alignment) {
    const MapAlignmentReport& a = *p.alignment;
    md += a.aligned
              ? fmt::format(
                    "\nThe other map aligned from the two files alone (as an attacker would: "
                    "density estimates, {} descriptor pairs, {} agreeing, refined on {} crossing "
                    "pairs, median line distance {:.2g} of the diagonal; scale {:.4g}, rotation "
                    "{:.2f}°). One estimate per line after alignment: the attacker's best "
                    "recovers {} ({} beyond what this map gives by itself: its own crossings and "
                    "the density attack).\n",
                    a.descriptor_pairs, a.ransac_inliers, a.refined_pairs,
                    a.median_line_distance_diagonal, a.scale, a.rotation_deg,
                    SharePercent(p.share_most_recovered_aligned.value_or(0)),
                    p.share_most_recovered_aligned_beyond_map
                        ? SharePercent(*p.share_most_recovered_aligned_beyond_map)
                        : "—")
              : fmt::format("\nThe other map could not be aligned with this one: {}.\n",
                            Cell(a.why_not));
  }
  return md;
}

}  // namespace

RecoverySummary SummarizeRecovery(const RecoveryScore& s) {
  RecoverySummary r;
  r.points = s.points;
  r.diagonal = s.diagonal;
  r.median_error = s.median_error;
  r.median_error_diagonal_percent = s.diagonal > 0 ? 100 * s.median_error / s.diagonal : 0.0;
  r.within_diagonal_percent = s.within_diagonal_percent;
  if (s.metric_scale > 0) {
    r.metric_scale = s.metric_scale;
    r.median_error_m = s.median_error * s.metric_scale;
    r.within_m = s.within_metres;
  }
  return r;
}

nlohmann::ordered_json ToJson(const AuditReport& r) {
  ojson j = {{"map", r.map},
             {"model", r.model},
             {"lines", r.lines},
             {"model_points", r.model_points},
             {"encoding", r.encoding},
             {"diagonal", r.diagonal},
             {"metric_scale", NumberOrNull(r.metric_scale)}};
  if (r.density_attack) j["density_attack"] = ToJson(*r.density_attack);
  if (r.two_keys) j["two_keys"] = ToJson(*r.two_keys);
  j["pairing_attacks"] = ToJson(r.pairing_attacks);
  return j;
}

AuditReport AuditReportFromJson(const nlohmann::json& j, const std::string& where) {
  const JsonFields f(j, where);
  AuditReport r;
  r.map = f.String("map");
  r.model = f.String("model");
  r.lines = f.Count("lines");
  r.model_points = f.Count("model_points");
  r.encoding = f.String("encoding");
  r.diagonal = f.NonNegative("diagonal");
  r.metric_scale = OptionalNonNegative(f, "metric_scale");
  if (f.Has("density_attack")) r.density_attack = DensityAttackFrom(f.Object("density_attack"));
  if (f.Has("two_keys")) r.two_keys = TwoKeyFrom(f.Object("two_keys"));
  r.pairing_attacks = PairingAttacksFrom(f.Object("pairing_attacks"), r.lines);
  if (r.density_attack && r.density_attack->lines_without_votes > r.lines) {
    Fail("{}: {} lines without votes in a map of {} lines",
         f.Object("density_attack").Where("lines_without_votes"),
         r.density_attack->lines_without_votes, r.lines);
  }
  return r;
}

std::string SharePercent(double share) { return fmt::format("{:.1f} %", 100 * share); }

std::string AuditMarkdown(const AuditReport& r) {
  std::string md = fmt::format("# Privacy audit of {}\n\n", Cell(r.map));
  md += fmt::format(
      "{} lines ({} encoding) lifted from {} ({} points); scene diagonal {:.4g} model "
      "units{}.\n\n",
      r.lines, Cell(r.encoding), Cell(r.model), r.model_points, r.diagonal,
      r.metric_scale ? fmt::format(" ({:.3g} m)", r.diagonal * *r.metric_scale) : "");
  if (r.density_attack) md += DensityAttackMarkdown(*r.density_attack);
  if (r.two_keys) md += TwoKeyMarkdown(*r.two_keys);
  md += PairingAttacksMarkdown(r.pairing_attacks);
  return md;
}

}  // namespace linecloud
