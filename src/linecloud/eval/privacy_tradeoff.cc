#include "linecloud/eval/privacy_tradeoff.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "linecloud/eval/eval_run.h"
#include "linecloud/draw/plot.h"
#include "linecloud/io/colmap_model.h"
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
ojson AttackGroupMaps(const EvalWork& work, const std::string& work_dir, const LiftingKey& key,
                      const MapLifting& lifting, const DensityAttackOptions& attack) {
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
  ojson j = {{"lines_per_map", static_cast<double>(lines) / std::max<size_t>(maps, 1)},
             {"within_0.5_percent", within[0] / lines},
             {"within_1_percent", within[1] / lines},
             {"within_2_percent", within[2] / lines},
             {"attack_seconds", seconds}};
  j["within_5cm"] = metric > 0 ? ojson(within_5cm / lines) : ojson(nullptr);
  return j;
}

ojson MethodFigures(const nlohmann::json& m) {
  return {{"localized", m.value("localized", 0)},
          {"queries", m.value("queries", 0)},
          {"median_rotation_deg", m.value("median_rotation_deg", NAN)},
          {"median_translation", m.value("median_translation", NAN)}};
}

ojson Localization(const nlohmann::json& report, const std::vector<std::string>& methods) {
  ojson j = ojson::object();
  for (const std::string& m : methods) {
    if (report.contains("methods") && report["methods"].contains(m)) {
      j["paper_protocol"][m] = MethodFigures(report["methods"][m]);
    }
    if (report.contains("direct_matching") && report["direct_matching"]["methods"].contains(m)) {
      j["direct_matching"][m] = MethodFigures(report["direct_matching"]["methods"][m]);
    }
  }
  return j;
}

// p6L's median rotation error: direct matching when run, else the paper's protocol.
double P6lRotation(const ojson& row) {
  const ojson& l = row["localization"];
  for (const char* protocol : {"direct_matching", "paper_protocol"}) {
    if (l.contains(protocol) && l[protocol].contains("p6L")) {
      return l[protocol]["p6L"]["median_rotation_deg"].get<double>();
    }
  }
  return NAN;
}

std::string Cell(const ojson& l, const char* protocol, const std::string& method) {
  if (!l.contains(protocol) || !l[protocol].contains(method)) return "–";
  const ojson& m = l[protocol][method];
  return fmt::format("{}/{}, {:.4f}° / {:.4f}", m["localized"].get<int>(), m["queries"].get<int>(),
                     m["median_rotation_deg"].get<double>(), m["median_translation"].get<double>());
}

std::string TradeoffMarkdown(const std::string& dataset, const ojson& rows,
                             const std::vector<std::string>& methods) {
  std::string md = fmt::format("# Privacy against accuracy — {}\n\n", dataset);
  md +=
      "Attack: the density attack (Chelani et al., CVPR 2021) on every group map as `lift` "
      "writes it, pooled; recovered = within 1 % of the map's diagonal (and 5 cm). "
      "Localization: `eval run` on the same maps (localized / queries, median rotation / "
      "translation error).\n\n| lifting | lines per map | recovered within 1 % (share / points per "
      "map) | within 5 cm |";
  for (const std::string& m : methods) md += fmt::format(" {} (paper protocol) |", m);
  md += " p6L (direct matching) |\n|---|---|---|---|";
  for (size_t i = 0; i < methods.size() + 1; ++i) md += "---|";
  md += "\n";
  for (const ojson& r : rows) {
    const ojson& a = r["attack"];
    md += fmt::format("| {} | {:.0f} | {:.1f} % / {:.0f} | {} |", r["lifting"].get<std::string>(),
                      a["lines_per_map"].get<double>(), 100 * a["within_1_percent"].get<double>(),
                      a["within_1_percent"].get<double>() * a["lines_per_map"].get<double>(),
                      a["within_5cm"].is_null()
                          ? "–"
                          : fmt::format("{:.1f} %", 100 * a["within_5cm"].get<double>()));
    for (const std::string& m : methods)
      md += fmt::format(" {} |", Cell(r["localization"], "paper_protocol", m));
    md += fmt::format(" {} |\n", Cell(r["localization"], "direct_matching", "p6L"));
  }
  // The target of [privacy]: recovery cut >= 3x, p6L error <= 1.5x, >= 90 % localized —
  // judged on the share of the map's points and on their number.
  const ojson& plain = rows.front();
  const double r0 = plain["attack"]["within_1_percent"].get<double>(), e0 = P6lRotation(plain);
  const double n0 = r0 * plain["attack"]["lines_per_map"].get<double>();
  md += fmt::format(
      "\nAgainst the plain lifting ({:.1f} % = {:.0f} points per map recovered, p6L "
      "{:.4f}°), liftings with p6L's error within 1.5× and ≥ 90 % localized that cut ",
      100 * r0, n0, e0);
  std::vector<std::string> by_share, by_count;
  for (const ojson& r : rows) {
    const double rec = r["attack"]["within_1_percent"].get<double>(), err = P6lRotation(r);
    const double count = rec * r["attack"]["lines_per_map"].get<double>();
    const ojson& l = r["localization"];
    const char* protocol = l.contains("direct_matching") ? "direct_matching" : "paper_protocol";
    if (!l.contains(protocol) || !l[protocol].contains("p6L")) continue;
    const ojson& p = l[protocol]["p6L"];
    const bool ok = err <= 1.5 * e0 && p["localized"].get<int>() >= 0.9 * p["queries"].get<int>();
    if (ok && rec * 3 <= r0) by_share.push_back(r["lifting"].get<std::string>());
    if (ok && count * 3 <= n0) by_count.push_back(r["lifting"].get<std::string>());
  }
  auto list = [](const std::vector<std::string>& v) {
    return v.empty() ? std::string("none") : fmt::format("{}", fmt::join(v, ", "));
  };
  md += fmt::format(
      "the recovered share by ≥ 3×: {}; the number of recovered points by ≥ 3×: {} "
      "(p6L: {}).\n",
      list(by_share), list(by_count),
      rows.front()["localization"].contains("direct_matching") ? "direct matching"
                                                               : "paper protocol");
  return md;
}

void TradeoffPlot(const std::string& path, const std::string& dataset, const ojson& rows) {
  // One series per family, starting at the plain lifting.
  std::map<std::string, PlotSeries> families;
  int color = 0;
  for (const ojson& r : rows) {
    const std::string name = r["lifting"].get<std::string>();
    const std::string family = name == "plain" ? "plain" : name.substr(0, name.find(' '));
    for (const std::string& f : {family}) {
      if (!families.count(f)) {
        PlotSeries s;
        s.name = f;
        s.color = color++;
        s.markers = true;
        if (f != "plain" && f != "compact" && f != "resist") {
          s.x.push_back(100 * rows.front()["attack"]["within_1_percent"].get<double>());
          s.y.push_back(P6lRotation(rows.front()));
          s.labels.push_back("");
        }
        families[f] = s;
      }
      families[f].x.push_back(100 * r["attack"]["within_1_percent"].get<double>());
      families[f].y.push_back(P6lRotation(r));
      families[f].labels.push_back(name);
    }
  }
  PlotOptions o;
  o.title = fmt::format("{}: what the density attack recovers against p6L's accuracy", dataset);
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

ojson RunPrivacyTradeoff(const PrivacyTradeoffOptions& o) {
  o.Check();
  const EvalWork work = ReadPreparedWork(o.work_dir);
  const LiftingKey key = EvalLiftingKey(o.work_dir);
  const std::vector<MapLifting> liftings =
      o.liftings.empty() ? DefaultTradeoffLiftings() : o.liftings;
  if (liftings.front().Name() != "plain")
    Fail("eval privacy: the first lifting must be the plain one");
  CreateDirectories(o.out_dir);
  ojson rows = ojson::array();
  const auto photos = std::make_shared<ExtractedPhotos>();  // SIFT once per photo
  for (const MapLifting& lifting : liftings) {
    if (o.progress) o.progress(fmt::format("{}: attack", lifting.Name()));
    ojson row = {{"lifting", lifting.Name()}};
    row["attack"] = AttackGroupMaps(work, o.work_dir, key, lifting, o.attack);
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
    row["localization"] = Localization(RunEvaluation(run), o.methods);
    rows.push_back(row);
  }
  const ojson report = {
      {"dataset", work.dataset}, {"units", work.units}, {"methods", o.methods}, {"liftings", rows}};
  WriteFileAtomically(JoinPaths(o.out_dir, "tradeoff.json"),
                      [&](std::ostream& out) { out << report.dump(2) << "\n"; });
  RenderPrivacyTradeoff(o.out_dir);
  return report;
}

void RenderPrivacyTradeoff(const std::string& out_dir) {
  const std::string path = JoinPaths(out_dir, "tradeoff.json");
  const ojson report = ojson::parse(ReadFileToString(path), nullptr, false);
  if (report.is_discarded() || !report.contains("liftings") || report["liftings"].empty()) {
    Fail("{}: not a tradeoff.json of eval privacy", path);
  }
  const std::string dataset = report.value("dataset", "");
  const std::vector<std::string> methods = report.contains("methods")
                                               ? report["methods"].get<std::vector<std::string>>()
                                               : std::vector<std::string>{"p6L", "p4L+u"};
  WriteFileAtomically(JoinPaths(out_dir, "tradeoff.md"), [&](std::ostream& out) {
    out << TradeoffMarkdown(dataset, report["liftings"], methods);
  });
  TradeoffPlot(JoinPaths(out_dir, "tradeoff.png"), dataset, report["liftings"]);
}

}  // namespace linecloud
