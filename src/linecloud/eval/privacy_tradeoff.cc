#include "linecloud/eval/privacy_tradeoff.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "linecloud/eval/eval_run.h"
#include "linecloud/draw/plot.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/io/json_util.h"
#include "linecloud/lifting/lifting.h"
#include "linecloud/privacy/recovery_score.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

using ojson = nlohmann::ordered_json;

std::string Slug(const std::string& name) {
  std::string s;
  for (const char c : name) {
    if (std::isalnum(static_cast<unsigned char>(c)) || c == '.')
      s += c;
    else if (!s.empty() && s.back() != '_')
      s += '_';
  }
  while (!s.empty() && s.back() == '_') s.pop_back();
  return s;
}

// The density attack on every group map as lifted, pooled over the maps.
TradeoffAttack AttackGroupMaps(const EvalWork& work, const std::string& work_dir,
                               const LiftingKey& key, const MapLifting& lifting,
                               const DensityAttackOptions& attack) {
  const double metric = work.units == "metres" ? 1.0 : 0.0;
  size_t lines = 0, maps = 0;
  double within[3] = {0, 0, 0}, within_5cm = 0, seconds = 0;
  const LiftingKey lines_key = MapLiftingKey(key, lifting);
  for (const EvalGroup& g : work.groups) {
    const Reconstruction model = ReadColmapModel(JoinPaths(work_dir, g.map_dir));
    const std::vector<uint64_t> ids = model.SortedPoint3DIds();
    const std::vector<Eigen::Vector3d> xyz = PointCoordinates(model, ids);
    const LineCloud cloud = LiftMap(key, ids, xyz, lifting);
    const std::vector<Eigen::Vector3d> secret =
        PointCoordinates(model, PointIdsOfLines(lines_key, cloud.ids));
    const DensityAttackResult r = RunDensityAttack(cloud, attack);
    const RecoveryScore s = ScoreRecovery(r.points, secret, metric);
    const double percents[3] = {0.5, 1.0, 2.0};
    for (int k = 0; k < 3; ++k) within[k] += ShareWithinDiagonal(s, percents[k]) * cloud.size();
    if (metric > 0) within_5cm += s.within_metres[1].second * cloud.size();
    lines += cloud.size();
    seconds += r.seconds;
    ++maps;
  }
  TradeoffAttack a;
  a.lines_per_map = static_cast<double>(lines) / std::max<size_t>(maps, 1);
  a.within_half_percent = within[0] / lines;
  a.within_1_percent = within[1] / lines;
  a.within_2_percent = within[2] / lines;
  if (metric > 0) a.within_5cm = within_5cm / lines;
  a.attack_seconds = seconds;
  return a;
}

TradeoffLocalization Figures(int localized, int queries, double rotation_deg, double translation) {
  return {localized, queries, rotation_deg, translation};
}

// A lifting's row from its `eval run` report.
void AddLocalization(const EvalReport& report, const std::vector<std::string>& methods,
                     TradeoffRow* row) {
  for (const std::string& name : methods) {
    if (const EvalMethodReport* m = FindIn(report.methods, name)) {
      row->paper_protocol[name] =
          Figures(m->localized, m->queries, m->median_rotation_deg, m->median_translation);
    }
    if (!report.direct_matching) continue;
    if (const DirectMatchingSummary* m = FindIn(report.direct_matching->methods, name)) {
      row->direct_matching[name] =
          Figures(m->localized, m->queries, m->median_rotation_deg, m->median_translation);
    }
  }
}

// p6L's figures: direct matching when run, else the paper's protocol.
const TradeoffLocalization* P6l(const TradeoffRow& row) {
  if (const TradeoffLocalization* d = FindIn(row.direct_matching, "p6L")) return d;
  return FindIn(row.paper_protocol, "p6L");
}
double P6lRotation(const TradeoffRow& row) {
  const TradeoffLocalization* p = P6l(row);
  return p ? p->median_rotation_deg : NAN;
}

std::string Cell(const std::map<std::string, TradeoffLocalization>& by_method,
                 const std::string& method) {
  const TradeoffLocalization* m = FindIn(by_method, method);
  if (!m) return "–";
  // No median without a localized query (null in the report).
  auto median = [](double v, const char* unit) {
    return std::isfinite(v) ? fmt::format("{:.4f}{}", v, unit) : std::string("–");
  };
  return fmt::format("{}/{}, {} / {}", m->localized, m->queries,
                     median(m->median_rotation_deg, "°"), median(m->median_translation, ""));
}

std::string TradeoffTable(const PrivacyTradeoffReport& r) {
  std::string md = fmt::format("# Privacy against accuracy — {}\n\n", r.dataset);
  md +=
      "Attack: the density attack (Chelani et al., CVPR 2021) on every group map as `lift` "
      "writes it, pooled; recovered = within 1 % of the map's diagonal (and 5 cm). "
      "Localization: `eval run` on the same maps (localized / queries, median rotation / "
      "translation error).\n\n| lifting | lines per map | recovered within 1 % (share / points per "
      "map) | within 5 cm |";
  for (const std::string& m : r.methods) md += fmt::format(" {} (paper protocol) |", m);
  md += " p6L (direct matching) |\n|---|---|---|---|";
  for (size_t i = 0; i < r.methods.size() + 1; ++i) md += "---|";
  md += "\n";
  for (const TradeoffRow& row : r.liftings) {
    const TradeoffAttack& a = row.attack;
    md += fmt::format("| {} | {:.0f} | {:.1f} % / {:.0f} | {} |", row.lifting, a.lines_per_map,
                      100 * a.within_1_percent, a.within_1_percent * a.lines_per_map,
                      a.within_5cm ? fmt::format("{:.1f} %", 100 * *a.within_5cm) : "–");
    for (const std::string& m : r.methods) md += fmt::format(" {} |", Cell(row.paper_protocol, m));
    md += fmt::format(" {} |\n", Cell(row.direct_matching, "p6L"));
  }
  return md;
}

// The target of [privacy]: recovery cut >= 3x, p6L error <= 1.5x, >= 90 % localized — judged on
// the share of the map's points and on their number.
std::string TradeoffVerdict(const PrivacyTradeoffReport& r) {
  const TradeoffRow& plain = r.liftings.front();
  const double r0 = plain.attack.within_1_percent, e0 = P6lRotation(plain);
  const double n0 = r0 * plain.attack.lines_per_map;
  std::string md = fmt::format(
      "\nAgainst the plain lifting ({:.1f} % = {:.0f} points per map recovered, p6L "
      "{:.4f}°), liftings with p6L's error within 1.5× and ≥ 90 % localized that cut ",
      100 * r0, n0, e0);
  std::vector<std::string> by_share, by_count;
  for (const TradeoffRow& row : r.liftings) {
    const TradeoffLocalization* p = P6l(row);
    if (!p) continue;
    const double rec = row.attack.within_1_percent, count = rec * row.attack.lines_per_map;
    const bool ok = p->median_rotation_deg <= 1.5 * e0 && p->localized >= 0.9 * p->queries;
    if (ok && rec * 3 <= r0) by_share.push_back(row.lifting);
    if (ok && count * 3 <= n0) by_count.push_back(row.lifting);
  }
  auto list = [](const std::vector<std::string>& v) {
    return v.empty() ? std::string("none") : fmt::format("{}", fmt::join(v, ", "));
  };
  md += fmt::format(
      "the recovered share by ≥ 3×: {}; the number of recovered points by ≥ 3×: {} "
      "(p6L: {}).\n",
      list(by_share), list(by_count),
      plain.direct_matching.empty() ? "paper protocol" : "direct matching");
  return md;
}

void TradeoffPlot(const std::string& path, const PrivacyTradeoffReport& r) {
  // One series per family, starting at the plain lifting.
  const TradeoffRow& plain = r.liftings.front();
  std::map<std::string, PlotSeries> families;
  int color = 0;
  for (const TradeoffRow& row : r.liftings) {
    const std::string& name = row.lifting;
    const std::string family = name == "plain" ? "plain" : name.substr(0, name.find(' '));
    if (!families.count(family)) {
      PlotSeries s;
      s.name = family;
      s.color = color++;
      s.markers = true;
      if (family != "plain" && family != "compact" && family != "resist") {
        s.x.push_back(100 * plain.attack.within_1_percent);
        s.y.push_back(P6lRotation(plain));
        s.labels.push_back("");
      }
      families[family] = s;
    }
    families[family].x.push_back(100 * row.attack.within_1_percent);
    families[family].y.push_back(P6lRotation(row));
    families[family].labels.push_back(name);
  }
  PlotOptions o;
  o.title = fmt::format("{}: what the density attack recovers against p6L's accuracy", r.dataset);
  o.x_label = "points recovered by the attack within 1 % of the scene diagonal (%)";
  o.y_label = "p6L median rotation error (°)";
  o.x_min = 0, o.x_max = 100;
  std::vector<PlotSeries> series;
  double y_max = 0;
  for (auto& [name, s] : families) {
    for (const double y : s.y) {
      if (std::isfinite(y)) y_max = std::max(y_max, y);
    }
    series.push_back(s);
  }
  o.y_min = 0, o.y_max = y_max > 0 ? 1.2 * y_max : 1;  // room for the labels
  WriteLinePlot(path, o, series);
}

ojson ToJson(const std::map<std::string, TradeoffLocalization>& by_method) {
  ojson j = ojson::object();
  for (const auto& [name, m] : by_method) {
    j[name] = {{"localized", m.localized},
               {"queries", m.queries},
               {"median_rotation_deg", m.median_rotation_deg},
               {"median_translation", m.median_translation}};
  }
  return j;
}

double NonNegativeOrNull(const JsonFields& f, const char* key) {
  return f.At(key).is_null() ? NAN : f.NonNegative(key);
}

std::map<std::string, TradeoffLocalization> LocalizationFrom(const JsonFields& f) {
  std::map<std::string, TradeoffLocalization> out;
  for (const auto& [name, value] : f.raw().items()) {
    const JsonFields m = f.Object(name.c_str());
    TradeoffLocalization l;
    l.queries = m.Int("queries");
    l.localized = m.Int("localized");
    if (l.queries < 0 || l.localized < 0 || l.localized > l.queries) {
      Fail("{}: {} localized of {} queries", m.Where("localized"), l.localized, l.queries);
    }
    l.median_rotation_deg = NonNegativeOrNull(m, "median_rotation_deg");
    if (l.median_rotation_deg > 180) {
      Fail("{}: {} is not an angle in [0, 180]", m.Where("median_rotation_deg"),
           l.median_rotation_deg);
    }
    l.median_translation = NonNegativeOrNull(m, "median_translation");
    out[name] = l;
  }
  return out;
}

// A lifting's or method's name as the report's table shows it: no cell
// separator, no line break, not a page long.
std::string CheckedName(const std::string& name, const std::string& where) {
  const bool plain = std::none_of(name.begin(), name.end(), [](char c) {
    return c == '|' || static_cast<unsigned char>(c) < 0x20;
  });
  if (name.empty() || name.size() > 100 || !plain) {
    Fail("{}: {} is not a name (1 to 100 characters, no '|' or control character)", where,
         ShownInMessage(nlohmann::json(name)));
  }
  return name;
}

TradeoffRow RowFrom(const JsonFields& f) {
  TradeoffRow row;
  row.lifting = CheckedName(f.String("lifting"), f.Where("lifting"));
  const JsonFields a = f.Object("attack");
  row.attack.lines_per_map = a.NonNegative("lines_per_map");
  if (row.attack.lines_per_map > 1e10) {
    Fail("{}: {} lines per map is not a map's", a.Where("lines_per_map"), row.attack.lines_per_map);
  }
  row.attack.within_half_percent = a.Share("within_0.5_percent");
  row.attack.within_1_percent = a.Share("within_1_percent");
  row.attack.within_2_percent = a.Share("within_2_percent");
  // Shares within growing thresholds cannot shrink.
  if (!(row.attack.within_half_percent <= row.attack.within_1_percent &&
        row.attack.within_1_percent <= row.attack.within_2_percent)) {
    Fail("{}: within 0.5 / 1 / 2 % ({} / {} / {}) must not decrease", a.where(),
         row.attack.within_half_percent, row.attack.within_1_percent, row.attack.within_2_percent);
  }
  if (!a.At("within_5cm").is_null()) row.attack.within_5cm = a.Share("within_5cm");
  row.attack.attack_seconds = a.NonNegative("attack_seconds");
  const JsonFields l = f.Object("localization");
  if (l.Has("paper_protocol")) row.paper_protocol = LocalizationFrom(l.Object("paper_protocol"));
  if (l.Has("direct_matching")) row.direct_matching = LocalizationFrom(l.Object("direct_matching"));
  return row;
}

}  // namespace

std::vector<MapLifting> QuickTradeoffLiftings() {
  MapLifting uniform, balanced, resist;
  uniform.sparsify = balanced.sparsify = 0.9;
  balanced.sparsify_mode = SparsifyMode::kBalanced;
  resist.resist_attack = 0.2;
  return {MapLifting{}, uniform, balanced, resist};
}

std::vector<MapLifting> DefaultTradeoffLiftings() {
  std::vector<MapLifting> l = {MapLifting{}};
  for (const SparsifyMode mode : {SparsifyMode::kUniform, SparsifyMode::kBalanced}) {
    for (const double drop : {0.5, 0.75, 0.9, 0.95}) {
      MapLifting m;
      m.sparsify = drop;
      m.sparsify_mode = mode;
      l.push_back(m);
    }
  }
  for (const double share : {0.2, 0.1}) {
    MapLifting m;
    m.resist_attack = share;
    l.push_back(m);
  }
  MapLifting compact;
  compact.compact = true;
  l.push_back(compact);
  return l;
}

void PrivacyTradeoffOptions::Check() const {
  if (work_dir.empty()) Fail("--work: empty");
  if (out_dir.empty()) Fail("--out: empty");
  for (const MapLifting& l : liftings) l.Check();
  attack.Check();
}

PrivacyTradeoffReport RunPrivacyTradeoff(const PrivacyTradeoffOptions& o) {
  o.Check();
  const EvalWork work = ReadPreparedWork(o.work_dir);
  const LiftingKey key = EvalLiftingKey(o.work_dir);
  const std::vector<MapLifting> liftings =
      o.liftings.empty() ? DefaultTradeoffLiftings() : o.liftings;
  if (liftings.front().Name() != "plain")
    Fail("eval privacy: the first lifting must be the plain one");
  CreateDirectories(o.out_dir);
  PrivacyTradeoffReport report{work.dataset, work.units, o.methods, {}};
  const auto photos = std::make_shared<ExtractedPhotos>();  // SIFT once per photo
  for (const MapLifting& lifting : liftings) {
    if (o.progress) o.progress(fmt::format("{}: attack", lifting.Name()));
    TradeoffRow row;
    row.lifting = lifting.Name();
    row.attack = AttackGroupMaps(work, o.work_dir, key, lifting, o.attack);
    if (o.progress) o.progress(fmt::format("{}: localization", lifting.Name()));
    EvalRunOptions run;
    run.work_dir = o.work_dir;
    run.out_dir = JoinPaths(o.out_dir, Slug(lifting.Name()));
    run.methods = o.methods;
    run.lifting = lifting;
    run.density_sweep.clear();
    run.noise_sweep.clear();
    run.direct_matching = o.direct_matching;
    run.extracted_photos = photos;
    AddLocalization(RunEvaluation(run), o.methods, &row);
    report.liftings.push_back(std::move(row));
  }
  WriteFileAtomically(JoinPaths(o.out_dir, "tradeoff.json"),
                      [&](std::ostream& out) { out << ToJson(report).dump(2) << "\n"; });
  RenderPrivacyTradeoff(o.out_dir);
  return report;
}

ojson ToJson(const PrivacyTradeoffReport& r) {
  ojson rows = ojson::array();
  for (const TradeoffRow& row : r.liftings) {
    const TradeoffAttack& a = row.attack;
    ojson attack = {{"lines_per_map", a.lines_per_map},
                    {"within_0.5_percent", a.within_half_percent},
                    {"within_1_percent", a.within_1_percent},
                    {"within_2_percent", a.within_2_percent},
                    {"attack_seconds", a.attack_seconds}};
    attack["within_5cm"] = a.within_5cm ? ojson(*a.within_5cm) : ojson(nullptr);
    ojson localization = ojson::object();
    if (!row.paper_protocol.empty()) localization["paper_protocol"] = ToJson(row.paper_protocol);
    if (!row.direct_matching.empty()) localization["direct_matching"] = ToJson(row.direct_matching);
    rows.push_back({{"lifting", row.lifting}, {"attack", attack}, {"localization", localization}});
  }
  return {{"dataset", r.dataset}, {"units", r.units}, {"methods", r.methods}, {"liftings", rows}};
}

PrivacyTradeoffReport PrivacyTradeoffFromJson(const nlohmann::json& j, const std::string& where) {
  const JsonFields f(j, where);
  PrivacyTradeoffReport r;
  r.dataset = f.String("dataset");
  r.units = f.String("units");
  r.dataset = CheckedName(r.dataset, f.Where("dataset"));
  const nlohmann::json& methods = f.Array("methods");
  constexpr size_t kMaxMethods = 64;  // the table's columns
  if (methods.empty() || methods.size() > kMaxMethods) {
    Fail("{}: {} methods (1 to {})", f.Where("methods"), methods.size(), kMaxMethods);
  }
  r.methods = f.Strings("methods");
  for (size_t i = 0; i < r.methods.size(); ++i) {
    CheckedName(r.methods[i], f.Where(fmt::format("methods[{}]", i)));
    if (std::find(r.methods.begin(), r.methods.begin() + i, r.methods[i]) !=
        r.methods.begin() + i) {
      Fail("{}: {} twice", f.Where(fmt::format("methods[{}]", i)), r.methods[i]);
    }
  }
  const nlohmann::json& rows = f.Array("liftings");
  // Checked before the rows are read: a forged file of many rows is refused at once.
  constexpr size_t kMaxLiftings = 1000;
  if (rows.size() > kMaxLiftings) {
    Fail("{}: {} liftings (at most {})", f.Where("liftings"), rows.size(), kMaxLiftings);
  }
  if (rows.empty() || !rows[0].is_object() || !rows[0].contains("lifting") ||
      rows[0]["lifting"] != "plain")
    Fail("{}: liftings must start with the plain one", f.Where("liftings"));
  for (size_t i = 0; i < rows.size(); ++i) {
    r.liftings.push_back(RowFrom(JsonFields(rows[i], f.Where(fmt::format("liftings[{}]", i)))));
    for (size_t k = 0; k < i; ++k) {
      if (r.liftings[k].lifting == r.liftings[i].lifting) {
        Fail("{}: {} twice (liftings[{}])", f.Where(fmt::format("liftings[{}].lifting", i)),
             r.liftings[i].lifting, k);
      }
    }
  }
  return r;
}

void RenderPrivacyTradeoff(const std::string& out_dir) {
  const std::string path = JoinPaths(out_dir, "tradeoff.json");
  const PrivacyTradeoffReport report = PrivacyTradeoffFromJson(ReadJsonFile(path), path);
  WriteFileAtomically(JoinPaths(out_dir, "tradeoff.md"), [&](std::ostream& out) {
    out << TradeoffTable(report) << TradeoffVerdict(report);
  });
  TradeoffPlot(JoinPaths(out_dir, "tradeoff.png"), report);
}

}  // namespace linecloud
