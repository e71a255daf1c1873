// The tables and JSON of `bench solvers` and `bench localize`, from their typed rows.
#include <fmt/format.h>

#include "linecloud/benchmarks/localization_bench.h"
#include "linecloud/benchmarks/solver_bench.h"

namespace linecloud {

nlohmann::json ToJson(const SolverBenchReport& report) {
  nlohmann::json rows = nlohmann::json::array();
  for (const SolverBenchRow& r : report.rows) rows.push_back(r.ToJson());
  return {{"seed", report.options.seed}, {"rows", rows}};
}

std::string SolverBenchMarkdown(const SolverBenchReport& report) {
  const SolverBenchOptions& o = report.options;
  std::string md = fmt::format(
      "fixed seed {}, {} noise-free instances per method, >= {:.1f} s timing each, one "
      "thread\n",
      o.seed, o.instances, o.min_seconds);
  md +=
      "µs/call: the solver on prepared inputs; API µs: the same call through\n"
      "SolveMinimal (sample conversion, output copy), as RANSAC makes it\n";
  md += fmt::format("| {:<29} | {:<29} | {:>9} | {:>8} | {:>9} | {:>8} | {:>10} | {:>14} |\n",
                    "method", "solver", "µs/call", "API µs", "solutions", "% true", "med log10",
                    "ours / peer");
  md +=
      "|-------------------------------|-------------------------------|-----------|"
      "----------|-----------|----------|------------|----------------|\n";
  double ours = 0;
  for (const SolverBenchRow& r : report.rows) {
    const bool mine = r.solver == "linecloud";
    if (mine) ours = r.us_per_call;
    md += fmt::format(
        "| {:<29} | {:<29} | {:>9.3f} | {:>8} | {:>9.2f} | {:>8.2f} | {:>10.1f} | {:>14} |\n",
        mine ? r.method : "", r.solver, r.us_per_call,
        mine ? fmt::format("{:.3f}", r.api_us_per_call) : std::string(""), r.mean_solutions,
        r.found_percent, r.median_log10_rotation_error,
        mine ? std::string("") : fmt::format("{:.2f}x", ours / r.us_per_call));
  }
  return md;
}

nlohmann::json ToJson(const LocalizationBenchReport& report) {
  const LocalizationBenchOptions& o = report.options;
  nlohmann::json rows = nlohmann::json::array();
  for (const LocalizationBenchRow& r : report.rows) rows.push_back(r.ToJson());
  return {{"seed", o.seed},
          {"inlier_ratio", o.instance.inlier_ratio},
          {"match_scores", o.instance.match_scores},
          {"progressive_sampling", o.localize.ransac.progressive_sampling},
          {"rows", rows}};
}

namespace {

// "0.95x p3P (1.02x)": the refined rotation error against the counterpart's,
// and the two maps' Cramér–Rao bounds.
std::string CounterpartRatio(const LocalizationBenchRow& r,
                             const std::vector<LocalizationBenchRow>& rows) {
  std::string ratio;
  for (const LocalizationBenchRow& other : rows) {
    if (other.method == r.counterpart && other.median_rotation_deg[1] > 0) {
      ratio = fmt::format("{:.2f}x {}", r.median_rotation_deg[1] / other.median_rotation_deg[1],
                          other.method);
    }
  }
  if (r.counterpart_rotation_bound_deg > 0) {
    ratio += fmt::format("{}({:.2f}x)", ratio.empty() ? "" : " ",
                         r.rotation_bound_deg / r.counterpart_rotation_bound_deg);
  }
  return ratio;
}

}  // namespace

std::string LocalizationBenchMarkdown(const LocalizationBenchReport& report) {
  const LocalizationBenchOptions& o = report.options;
  std::string md = fmt::format(
      "seed {}, {} queries per method, {} correspondences, {:.0f} % inliers, {:.1f} px noise, "
      "threshold {:.1f} px, {}, one thread; localized = refined within {:.1f} deg and {:.1f} % "
      "of the scene size\n",
      o.seed, o.queries, o.instance.num_correspondences, 100 * o.instance.inlier_ratio,
      o.instance.noise_px, o.localize.ransac.max_error,
      !o.instance.match_scores                 ? "no match scores (uniform samples)"
      : o.localize.ransac.progressive_sampling ? "match ratios as on real photos, PROSAC samples"
                                               : "match ratios as on real photos, uniform samples",
      o.max_rotation_deg, 100 * o.max_position_rel);
  md +=
      "| method | localized | confident wrong | rot. deg init / ref | rot. bound deg | pos. % "
      "init / ref | iters | inliers | sols | solver us | RANSAC ms (solver / scoring / LO) | "
      "refine ms (iters) | total ms mean / median | ref. rot. / counterpart (bound) |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const LocalizationBenchRow& r : report.rows) {
    md += fmt::format(
        "| {} | {:.1f} % | {} | {:.4f} / {:.4f} | {:.4f} | {:.3f} / {:.3f} | {:.0f} | {:.0f} % | "
        "{:.2f} | {:.2f} | {:.3f} ({:.1f} / {:.1f} / {:.1f}) | {:.3f} ({:.1f}) | {:.3f} / {:.3f} "
        "| {} |\n",
        r.method, r.queries ? 100.0 * r.localized / r.queries : 0.0, r.confident_wrong,
        r.median_rotation_deg[0], r.median_rotation_deg[1], r.rotation_bound_deg,
        100 * r.median_position[0], 100 * r.median_position[1], r.iterations, 100 * r.inlier_ratio,
        r.solutions, r.solver_us, r.ransac_ms, r.solver_ms, r.scoring_ms, r.lo_ms, r.refine_ms,
        r.refine_iterations, r.total_ms, r.median_total_ms, CounterpartRatio(r, report.rows));
  }
  md +=
      "rot. bound: Cramer-Rao bound of the refined rotation (RMS over noise "
      "realisations, at the true pose on the true inliers; median over queries); "
      "(bound): the ratio of the two maps' bounds on the same queries; confident wrong: poses the "
      "success criteria accept (inliers, ratio, runner-up, uncertainty; no calibration check) "
      "farther than the thresholds\n";
  return md;
}

}  // namespace linecloud
