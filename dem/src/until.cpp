#include "dem/until.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace lw::dem {
namespace {

/// -slope of log(band) on log(steady span) over the steps (least squares); NaN with fewer than two
/// distinct spans.
double MeasuredExponent(const std::vector<BandAfter>& so_far) {
  double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (const BandAfter& b : so_far) {
    if (!(b.steady_s > 0 && b.half_width_mm > 0)) continue;
    const double x = std::log(b.steady_s), y = std::log(b.half_width_mm);
    n += 1, sx += x, sy += y, sxx += x * x, sxy += x * y;
  }
  const double var = sxx - sx * sx / std::max(n, 1.0);
  if (n < 2 || !(var > 1e-12)) return std::numeric_limits<double>::quiet_NaN();
  return -(sxy - sx * sy / n) / var;
}

}  // namespace

UntilStep PlanUntilStep(const std::vector<BandAfter>& so_far, double target_mm, const UntilBudget& budget) {
  if (so_far.empty()) throw std::invalid_argument("PlanUntilStep needs the band of at least one step");
  const BandAfter& last = so_far.back();
  UntilStep s;
  const double measured = MeasuredExponent(so_far);
  if (std::isfinite(measured)) {
    s.exponent = std::clamp(measured, 0.05, 1.0);
    s.measured = true;
  }
  if (last.half_width_mm <= target_mm) {
    s.verdict = UntilStep::Verdict::kDone;
    s.needed_steady_s = last.steady_s;
    s.projected_simulated_s = s.next_simulated_s = last.simulated_s;
    s.projected_wall_s = s.step_wall_s = 0;
    return s;
  }
  // A span beyond a million simulated seconds is a band that does not fall: say so in numbers, not inf.
  s.needed_steady_s = std::min(1e6, last.steady_s * std::pow(last.half_width_mm / target_mm, 1.0 / s.exponent));
  s.projected_simulated_s = last.simulated_s + std::max(0.0, s.needed_steady_s - last.steady_s);
  const double rate = budget.wall_per_simulated_s;
  const bool known = std::isfinite(rate) && rate > 0;
  if (known) s.projected_wall_s = rate * (s.projected_simulated_s - budget.resume_from_s);
  // At most twice the run so far per step: the band is measured again before the run goes further.
  double next = std::min(s.projected_simulated_s, 2.0 * last.simulated_s);
  next = std::max(next, last.simulated_s + budget.min_step_s);
  const double dump = budget.dump_interval_s > 0 ? budget.dump_interval_s : 1.0;
  next = std::ceil(next / dump - 1e-9) * dump;
  if (known && rate * (next - budget.resume_from_s) > budget.remaining_wall_s) {
    // What fits in the time left, with a tenth spare for the map and the re-run from the restart.
    next = std::floor((budget.resume_from_s + 0.9 * budget.remaining_wall_s / rate) / dump + 1e-9) * dump;
  }
  s.next_simulated_s = next;
  if (known) s.step_wall_s = rate * (next - budget.resume_from_s);
  s.verdict = budget.remaining_wall_s > 0 && next >= last.simulated_s + budget.min_step_s - 1e-9 ? UntilStep::Verdict::kStep
                                                                                                 : UntilStep::Verdict::kBudget;
  return s;
}

}  // namespace lw::dem
