// report.md of `eval run`, from the typed report alone (the paper's Table 2 layout, the
// Cramér–Rao check, the sweeps and direct matching).
#include <cmath>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "linecloud/benchmarks/localization_bench.h"
#include "linecloud/eval/eval_report.h"
#include "linecloud/eval/paper_table2.h"
#include "linecloud/solvers/minimal_problem.h"

namespace linecloud {
namespace {

std::string Fixed(double v, int decimals) {
  return std::isfinite(v) ? fmt::format("{:.{}f}", v, decimals) : "–";
}

// A markdown table: one row per method (paper order), one column per sweep level.
std::string SweepTable(const std::vector<std::string>& columns,
                       const std::map<std::string, std::vector<double>>& values_by_method) {
  std::string md = "| method |";
  for (const std::string& c : columns) md += fmt::format(" {} |", c);
  md += "\n|---|";
  for (size_t i = 0; i < columns.size(); ++i) md += "---|";
  md += "\n";
  for (const MethodInfo& info : AllMethods()) {
    const auto it = values_by_method.find(std::string(info.name));
    if (it == values_by_method.end()) continue;
    md += fmt::format("| {} |", info.name);
    for (double x : it->second) md += fmt::format(" {} |", Fixed(x, 3));
    md += "\n";
  }
  return md;
}

std::string Header(const EvalReport& r) {
  std::string md = fmt::format("# linecloud eval — {}\n\n", r.dataset);
  md += fmt::format(
      "Units: {}. RANSAC threshold {} px for every method; seed {}; map sparsified by {:.0f} %; "
      "extra pixel noise σ = {} px.\n\n",
      r.units, r.threshold_px, r.seed, 100 * r.sparsify, r.noise_px);
  if (const auto g = r.ground_truth()) {
    md += fmt::format(
        "COLMAP reconstruction vs. ground truth, after a similarity alignment on {} cameras "
        "(rotation from their orientations, scale and translation from their centres): "
        "max {:.3f}° / {:.4f} m.\n\n",
        g->aligned_on, g->max_rotation_deg, g->max_position_m);
  }
  md += fmt::format("Gravity (+u): {}.\n\n", r.gravity_source);
  return md;
}

std::string Table2(const EvalReport& r) {
  std::string md =
      "Table 2 layout. Rotation error (°) and translation error; `loc.` = within 1° and 0.1; "
      "iterations, inlier ratio, solutions and solver time are means per query; reprojection "
      "errors (px) are means over the inliers: point-to-line for line methods with the "
      "point-to-point error against the secret points in brackets. Paper = Speciale et al., "
      "CVPR 2019, Table 2.\n\n"
      "| method | queries | loc. | rot. init / ref. | trans. init / ref. | iters | inliers % | "
      "solutions | solver µs | reproj. init / ref. px | paper: iters / inl. % / sol. | paper "
      "reproj. |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const MethodInfo& info : AllMethods()) {
    const EvalMethodReport* m = FindIn(r.methods, info.name);
    if (!m) continue;
    const ReprojectionErrors& rp = m->reprojection_px;
    std::string reproj = Fixed(rp.initial, 2) + " / " + Fixed(rp.refined, 2);
    if (info.lines) {
      reproj = fmt::format("{} ({}) / {} ({})", Fixed(rp.initial, 2), Fixed(rp.point_initial, 2),
                           Fixed(rp.refined, 2), Fixed(rp.point_refined, 2));
    }
    std::string paper = "–", paper_reproj = "–";
    if (const PaperRow* p = PaperFor(info.name)) {
      paper = fmt::format("{:g} / {:g} / {:g}", p->iterations, p->inlier_percent, p->solutions);
      if (p->reprojection_initial > 0)
        paper_reproj =
            fmt::format("{:.2f} / {:.2f}", p->reprojection_initial, p->reprojection_refined);
    }
    md += fmt::format(
        "| {} | {} | {} | {} / {} | {} / {} | {:.1f} | {:.0f} | {:.2f} | {:.1f} | {} | {} | {} |\n",
        info.name, m->queries, m->localized, Fixed(m->median_rotation_deg_initial, 3),
        Fixed(m->median_rotation_deg, 3), Fixed(m->median_translation_initial, 4),
        Fixed(m->median_translation, 4), m->mean_iterations, 100 * m->inlier_ratio,
        m->mean_solutions, m->solver_us, reproj, paper, paper_reproj);
  }
  return md;
}

std::string CramerRao(const EvalReport& r) {
  std::string md =
      "\n## Cramér–Rao check of the refined rotation\n\n"
      "How close each method comes to the least rotation error any estimator could reach on its "
      "inliers: σ̂ = the observation noise at the ground truth (median reprojection error of the "
      "inliers' points / √(2 ln 2)), bound = √trace of the Cramér–Rao covariance of the rotation "
      "at the ground truth with σ̂ (eq. 2 residuals for points, eq. 6 for lines: a line measures "
      "only the offset across it), medians over the queries; RMS error / bound ≈ 1 for an "
      "efficient estimator. The bound ratio is the least by which the line method must trail its "
      "point twin on these queries.\n\n"
      "| point / line method | σ̂ px | refined rot. ° point / line (ratio) | bound ° point / line "
      "(ratio) | RMS error / bound point / line |\n|---|---|---|---|---|\n";
  for (const MethodInfo& info : AllMethods()) {
    if (info.lines) continue;
    const EvalMethodReport* p = FindIn(r.methods, info.name);
    const EvalMethodReport* l = FindIn(r.methods, CounterpartMethod(info));
    if (!p || !l) continue;
    const double rp = p->median_rotation_deg, rl = l->median_rotation_deg;
    const double bp = p->median_rotation_bound_deg, bl = l->median_rotation_bound_deg;
    md += fmt::format("| {} / {} | {} | {} / {} ({}×) | {} / {} ({}×) | {} / {} |\n", info.name,
                      CounterpartMethod(info), Fixed(p->median_noise_px, 2), Fixed(rp, 4),
                      Fixed(rl, 4), Fixed(rl / rp, 2), Fixed(bp, 4), Fixed(bl, 4),
                      Fixed(bl / bp, 2), Fixed(p->rms_rotation_error_over_bound.value_or(NAN), 2),
                      Fixed(l->rms_rotation_error_over_bound.value_or(NAN), 2));
  }
  return md;
}

std::string DirectMatchingMarkdown(const DirectMatchingReport& d) {
  std::string md = fmt::format(
      "\n## Direct matching (the deployable protocol)\n\nEach query image's own SIFT features "
      "(COLMAP 3.8's CPU extractor reproduced) matched to the map's descriptors (medoids of the "
      "map images' observations only), then the same RANSAC, refinement and success criteria as "
      "`localize --image`; the m- methods take each group's photos as one rig (`localize "
      "--image A --image B --rig RIG.json`). Localized: within {}° and {} units of the ground "
      "truth.\n\n"
      "| method | queries | localized | median rot. ° | median transl. | extract ms | match ms | "
      "RANSAC ms | refine ms |\n|---|---|---|---|---|---|---|---|---|\n",
      d.max_rotation_deg, d.max_translation);
  for (const auto& [name, m] : d.methods) {
    md += fmt::format("| {} | {} | {} | {:.4f} | {:.4f} | {:.0f} | {:.0f} | {:.1f} | {:.1f} |\n",
                      name, m.queries, m.localized, m.median_rotation_deg, m.median_translation,
                      m.mean_ms.extract, m.mean_ms.match, m.mean_ms.ransac, m.mean_ms.refine);
  }
  return md;
}

std::string Sweeps(const EvalReport& r) {
  std::string md;
  if (r.density) {
    std::vector<std::string> columns;
    for (double f : r.density->levels) columns.push_back(fmt::format("{:.0f} %", 100 * f));
    md +=
        "\n## Error vs. map density (Fig. 7)\n\nMedian refined rotation error (°) when a share of "
        "the map's points (and the same lines) is dropped at random.\n\n" +
        SweepTable(columns, r.density->median_rotation_deg);
  }
  if (r.direct_matching) md += DirectMatchingMarkdown(*r.direct_matching);
  if (r.noise) {
    std::vector<std::string> columns;
    for (double f : r.noise->levels) columns.push_back(fmt::format("{:g} px", f));
    md +=
        "\n## Error vs. pixel noise, synthetic (Fig. 8)\n\nMedian refined rotation error (°).\n\n" +
        SweepTable(columns, r.noise->median_rotation_deg);
  }
  return md;
}

}  // namespace

std::string EvalReportMarkdown(const EvalReport& report) {
  return Header(report) + Table2(report) + CramerRao(report) + Sweeps(report);
}

}  // namespace linecloud
