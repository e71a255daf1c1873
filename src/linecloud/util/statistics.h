// Small summary statistics for benchmarks and reports.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

namespace linecloud {

// Arithmetic mean; 0 for no values.
inline double Mean(const std::vector<double>& values) {
  double sum = 0;
  for (const double v : values) sum += v;
  return values.empty() ? 0.0 : sum / static_cast<double>(values.size());
}

// Upper median (the element at n/2 after sorting); 0 for no values.
inline double Median(std::vector<double> values) {
  if (values.empty()) return 0;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

// The p-th percentile (0 <= p <= 100) by nearest rank: the smallest value
// with at least p % of the values at or below it; 0 for no values.
inline double Percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const double rank = std::ceil(p / 100.0 * static_cast<double>(values.size()));
  const size_t at = static_cast<size_t>(std::clamp(rank, 1.0, double(values.size()))) - 1;
  return values[at];
}

}  // namespace linecloud
