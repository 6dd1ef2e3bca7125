#pragma once
/// Summary statistics the benchmarks print (header-only; benches are programs, not a library).
#include <algorithm>
#include <vector>

namespace lw::bench {

/// The upper median of `v` (the middle element after sorting; for an even count the larger of the
/// two middle ones), 0 for an empty vector. Repetition counts are small: sorting a copy is fine.
inline double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace lw::bench
