// Line plots written as PNG with cairo: the evaluation's figures (cumulative
// error curves, error vs. map density, error vs. pixel noise).
#pragma once

#include <string>
#include <vector>

namespace linecloud {

struct PlotSeries {
  std::string name;
  std::vector<double> x, y;
  int color = 0;                    // index into a fixed palette
  bool dashed = false;              // e.g. the privacy-preserving (line) twin of a method
  bool markers = false;             // a dot at each point
  std::vector<std::string> labels;  // optional: a label beside each point
};

struct PlotOptions {
  std::string title, x_label, y_label;
  bool log_x = false;
  bool log_y = false;
  double x_min = 0, x_max = 0;  // x_max <= x_min: from the data
  double y_min = 0, y_max = 0;  // likewise
  int width = 1100, height = 700;
};

// Throws Error naming `path` when the PNG cannot be written. Non-finite
// points are skipped.
void WriteLinePlot(const std::string& path, const PlotOptions& options,
                   const std::vector<PlotSeries>& series);

}  // namespace linecloud
