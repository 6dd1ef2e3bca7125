#pragma once
/// Time-series steps of map building that need no files: where the chamber runs steady (choke fed)
/// and how that span splits into independent time windows.
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace lw::dem {

struct SteadyWindow {
  bool found = false;
  double t_start = 0;  ///< s: from here on the chamber mass stays within the band
  double t_end = 0;    ///< s: last sample
  double level = 0;    ///< plateau level (median of the last quarter of samples)
  double band = 0;     ///< accepted deviation from the level
  double drift = 0;    ///< relative change of the mass over the steady span (linear fit)
  std::string reason;  ///< why not found, or a caution
};

/// The steady span of a chamber-mass series m(t) (samples in time order): the plateau level is the
/// median of the last quarter; the span starts at the first sample after which every sample stays
/// within max(rel_tol * level, min(3 robust sd of the last quarter, 3 rel_tol * level)) of it.
/// Not found when the chamber never fills (level <= 0), the series is shorter than 8 samples, the
/// plateau is under `min_fraction` of the run, or the mass still drifts by more than 2 rel_tol
/// over it (a caution in `reason` above rel_tol).
SteadyWindow DetectSteadyWindow(const std::vector<double>& t, const std::vector<double>& mass, double rel_tol = 0.05,
                                double min_fraction = 0.2);

/// How many windows a steady span of `span_s` gives with windows of at least `min_window_s`:
/// `requested` when > 0 (and feasible), else as many as fit, at most `max_windows`. Returns 0 when
/// not even 2 fit.
int ChooseWindowCount(double span_s, double min_window_s, int requested, int max_windows = 8);

/// Splits the dumps [first, last] (indices into a time-ordered list, `last - first` intervals) into
/// `k` consecutive windows of as equal a number of intervals as possible: each window is
/// (begin dump, end dump); window i's increment is value(end) - value(begin). Throws
/// std::invalid_argument when k < 1 or there are fewer intervals than windows.
std::vector<std::pair<size_t, size_t>> SplitWindows(size_t first, size_t last, int k);

}  // namespace lw::dem
