#pragma once
/// Medians of samples, one rule for every program: robust centres and scales (the map model, scan
/// cells, the diagnosis' sensor steps, the DEM run's steady window).
#include <algorithm>
#include <cstddef>
#include <limits>
#include <vector>

namespace lw::core {

/// The middle value of `v`; of an even count the upper of the two middle ones, so the answer is
/// always one of the samples (a robust level or scale compared with the samples themselves).
/// `if_empty` when there is none.
inline double UpperMedian(std::vector<double> v, double if_empty = 0) {
  if (v.empty()) return if_empty;
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  return v[mid];
}

/// The median: of an even count the mean of the two middle values. NaN when `v` is empty.
inline double Median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const size_t n = v.size(), mid = n / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  if (n % 2) return v[mid];
  return 0.5 * (*std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid)) + v[mid]);
}

}  // namespace lw::core
