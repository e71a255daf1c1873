// Small summary statistics for benchmarks and reports.
#pragma once

#include <algorithm>
#include <vector>

namespace linecloud {

// Upper median (the element at n/2 after sorting); 0 for no values.
inline double Median(std::vector<double> values) {
  if (values.empty()) return 0;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

}  // namespace linecloud
