#pragma once
/// `linerwatch dem --until-band`: whether a DEM run's map is precise enough, and if not how much
/// more simulated time to run next, from the band the map gave after each step so far.
#include <limits>
#include <vector>

namespace lw::dem {

/// The map's band after one step (estimate::MapBandAt on the map built from the run so far).
struct BandAfter {
  double simulated_s = 0;    ///< the run's simulated time, filling included
  double steady_s = 0;       ///< its steady span, which the windows cover
  double half_width_mm = 0;  ///< the band's half-width at the patch
};

struct UntilBudget {
  /// Wall seconds per simulated second, measured on this case (NaN: not known yet).
  double wall_per_simulated_s = std::numeric_limits<double>::quiet_NaN();
  double resume_from_s = 0;                                           ///< the newest restart's time: a step re-runs from there
  double remaining_wall_s = std::numeric_limits<double>::infinity();  ///< what is left of --max-hours
  double dump_interval_s = 0.5;                                       ///< a step ends on a dump
  double min_step_s = 0.5;                                            ///< the least simulated time a step adds (a window's worth)
};

struct UntilStep {
  enum class Verdict { kDone, kStep, kBudget };
  Verdict verdict = Verdict::kDone;
  /// The band falls as steady_s^-exponent: measured over the steps so far (two or more, a
  /// least-squares fit in log-log, kept within [0.05, 1]), else 1/2, the sampling noise's law.
  double exponent = 0.5;
  bool measured = false;
  double needed_steady_s = 0;                                          ///< the steady span the target needs at that exponent
  double projected_simulated_s = 0;                                    ///< the run's simulated time then (the steady start stays)
  double projected_wall_s = std::numeric_limits<double>::quiet_NaN();  ///< wall time from now to there (NaN: rate unknown)
  double next_simulated_s = 0;  ///< where this step ends: the projection, at most twice the run so far, within the budget
  double step_wall_s = std::numeric_limits<double>::quiet_NaN();  ///< this step's expected wall time
};

/// The next step after `so_far` (at least one entry): kDone when the last band is within
/// `target_mm`; kBudget when not even `min_step_s` more fits in the remaining wall time at the
/// measured rate (or no time is left); else kStep to next_simulated_s (a whole number of dumps).
UntilStep PlanUntilStep(const std::vector<BandAfter>& so_far, double target_mm, const UntilBudget& budget);

}  // namespace lw::dem
