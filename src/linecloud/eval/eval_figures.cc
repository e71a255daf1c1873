// The PNG figures of `eval run`, from the typed report alone (Figs. 5, 7 and 8 of Speciale et
// al., CVPR 2019).
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "linecloud/draw/plot.h"
#include "linecloud/eval/eval_report.h"
#include "linecloud/solvers/minimal_problem.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

// Pair colours: a point method and its line twin share a colour; lines dashed.
int PairColor(const MethodInfo& m) {
  const auto all = AllMethods();
  for (size_t i = 0; i < all.size(); ++i) {
    if (all[i].name == m.name) return static_cast<int>(i % 8);
  }
  return 0;
}

std::vector<double> CumulativeAt(std::vector<double> errors, const std::vector<double>& xs) {
  std::sort(errors.begin(), errors.end());
  std::vector<double> y;
  for (double x : xs) {
    const auto it = std::upper_bound(errors.begin(), errors.end(), x);
    y.push_back(errors.empty() ? 0.0 : 100.0 * (it - errors.begin()) / errors.size());
  }
  return y;
}

// Fig. 5: cumulative refined errors over the queries of each method.
void WriteCumulativeFigures(const EvalReport& report, const std::string& out_dir) {
  std::vector<double> xr, xt;
  // Log-spaced: 1e-3° .. 10°, 1e-4 .. 10 units.
  for (int i = 0; i <= 200; ++i) xr.push_back(std::pow(10.0, -3 + 4.0 * i / 200));
  for (int i = 0; i <= 250; ++i) xt.push_back(std::pow(10.0, -4 + 5.0 * i / 250));
  std::vector<PlotSeries> rs, ts;
  for (const MethodInfo& m : AllMethods()) {
    const EvalMethodReport* mr = FindIn(report.methods, m.name);
    if (!mr) continue;
    std::vector<double> r, t;
    for (const EvalQueryResult& q : mr->per_query) {
      r.push_back(q.rotation_deg.refined);
      t.push_back(q.translation.refined);
    }
    const std::string name(m.name);
    rs.push_back({name, xr, CumulativeAt(r, xr), PairColor(m), m.lines, false, {}});
    ts.push_back({name, xt, CumulativeAt(t, xt), PairColor(m), m.lines, false, {}});
  }
  WriteLinePlot(JoinPaths(out_dir, "cumulative_rotation.png"),
                {.title = report.dataset + ": cumulative rotation error (refined)",
                 .x_label = "rotation error (deg)",
                 .y_label = "queries (%)",
                 .log_x = true,
                 .y_min = 0,
                 .y_max = 100},
                rs);
  WriteLinePlot(JoinPaths(out_dir, "cumulative_translation.png"),
                {.title = report.dataset + ": cumulative translation error (refined)",
                 .x_label = "translation error (" + report.units + ")",
                 .y_label = "queries (%)",
                 .log_x = true,
                 .y_min = 0,
                 .y_max = 100},
                ts);
}

// A sweep's median rotation errors, one series per method, x scaled by `x_scale`.
void WriteSweepFigure(const EvalSweep& sweep, double x_scale, const std::string& path,
                      const PlotOptions& options) {
  std::vector<double> x;
  for (double level : sweep.levels) x.push_back(x_scale * level);
  std::vector<PlotSeries> series;
  for (const MethodInfo& m : AllMethods()) {
    if (const std::vector<double>* y = FindIn(sweep.median_rotation_deg, m.name))
      series.push_back({std::string(m.name), x, *y, PairColor(m), m.lines, false, {}});
  }
  WriteLinePlot(path, options, series);
}

}  // namespace

void WriteEvalFigures(const EvalReport& report, const std::string& out_dir) {
  WriteCumulativeFigures(report, out_dir);
  if (report.density) {
    WriteSweepFigure(*report.density, 100, JoinPaths(out_dir, "error_vs_density.png"),
                     {.title = report.dataset + ": median rotation error vs. map density",
                      .x_label = "points / lines dropped (%)",
                      .y_label = "median rotation error (deg)",
                      .log_y = true});
  }
  if (report.noise) {
    WriteSweepFigure(*report.noise, 1, JoinPaths(out_dir, "error_vs_noise.png"),
                     {.title = "synthetic scene: median rotation error vs. pixel noise",
                      .x_label = "pixel noise σ (px)",
                      .y_label = "median rotation error (deg)",
                      .log_y = true});
  }
}

}  // namespace linecloud
