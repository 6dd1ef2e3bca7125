#include "dem/series.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/median.hpp"

namespace lw::dem {
SteadyWindow DetectSteadyWindow(const std::vector<double>& t, const std::vector<double>& mass, double rel_tol,
                                double min_fraction) {
  SteadyWindow w;
  if (t.size() != mass.size()) throw std::invalid_argument("time and mass series differ in length");
  const size_t n = t.size();
  if (n < 8) {
    w.reason = "only " + std::to_string(n) + " samples of the chamber mass (at least 8 needed)";
    return w;
  }
  const size_t tail = std::max<size_t>(2, n / 4);
  std::vector<double> last(mass.end() - static_cast<long>(tail), mass.end());
  w.level = core::Median(last);
  if (!(w.level > 0)) {
    w.reason = "the chamber never filled (no mass in it at the end of the run)";
    return w;
  }
  std::vector<double> dev;
  for (double m : last) dev.push_back(std::abs(m - w.level));
  const double robust_sd = 1.4826 * core::Median(dev);
  // A noisy plateau widens the band, but never past 3 x rel_tol: a ramp is not a plateau.
  w.band = std::max(rel_tol * w.level, std::min(3.0 * robust_sd, 3.0 * rel_tol * w.level));
  size_t start = n;  // first index of the final run of in-band samples
  for (size_t i = n; i-- > 0;) {
    if (std::abs(mass[i] - w.level) > w.band) break;
    start = i;
  }
  if (start >= n) {
    w.reason = "the chamber mass never settles within the band";
    return w;
  }
  w.t_start = t[start];
  w.t_end = t[n - 1];
  const double run = t[n - 1] - t[0];
  if (run <= 0 || (w.t_end - w.t_start) < min_fraction * run) {
    w.reason = "the steady span (" + std::to_string(w.t_end - w.t_start) + " s) is under " +
               std::to_string(static_cast<int>(min_fraction * 100)) + " % of the run: simulate longer";
    return w;
  }
  // Drift over the steady span: least-squares slope times the span, relative to the level.
  double st = 0, sm = 0, stt = 0, stm = 0, k = 0;
  for (size_t i = start; i < n; ++i) {
    st += t[i], sm += mass[i], stt += t[i] * t[i], stm += t[i] * mass[i], k += 1;
  }
  const double denom = k * stt - st * st;
  const double slope = denom > 0 ? (k * stm - st * sm) / denom : 0.0;
  w.drift = slope * (w.t_end - w.t_start) / w.level;
  const std::string drift = std::to_string(static_cast<int>(std::lround(100 * w.drift)));
  if (std::abs(w.drift) > 2 * rel_tol) {
    w.reason = "the chamber mass still changes by " + drift + " % over the last part of the run: simulate longer";
    return w;
  }
  if (std::abs(w.drift) > rel_tol) w.reason = "the chamber mass still drifts by " + drift + " % over the steady span";
  w.found = true;
  return w;
}

int ChooseWindowCount(double span_s, double min_window_s, int requested, int max_windows) {
  if (span_s <= 0 || min_window_s <= 0) return 0;
  const int fit = static_cast<int>(std::floor(span_s / min_window_s + 1e-9));
  if (requested > 0) return requested <= fit ? requested : 0;
  const int k = std::min(fit, max_windows);
  return k >= 2 ? k : 0;
}

std::vector<std::pair<size_t, size_t>> SplitWindows(size_t first, size_t last, int k) {
  if (k < 1) throw std::invalid_argument("at least one window is needed");
  if (last < first || last - first < static_cast<size_t>(k))
    throw std::invalid_argument("fewer dump intervals (" + std::to_string(last >= first ? last - first : 0) + ") than windows (" +
                                std::to_string(k) + ")");
  const size_t intervals = last - first;
  std::vector<std::pair<size_t, size_t>> w;
  size_t begin = first;
  for (int i = 1; i <= k; ++i) {
    const size_t end = first + (intervals * static_cast<size_t>(i) + static_cast<size_t>(k) / 2) / static_cast<size_t>(k);
    w.push_back({begin, end});
    begin = end;
  }
  w.back().second = last;
  return w;
}

}  // namespace lw::dem
