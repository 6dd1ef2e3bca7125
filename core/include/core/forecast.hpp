#pragma once
/// Remaining-life forecast: per sensor, a wear curve fitted to its recent readings that may
/// accelerate (never assumed to slow down), extrapolated to the date the liner reaches its minimum
/// thickness, with a band; per row, the thinnest face (from the Eq. 9 reconstruction) carried along
/// the row's sensor curves. A reading n means thickness in [n, n+1) mm: fits use n + 0.5 and a
/// quantisation error of 1/sqrt(12) mm at least.
#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "core/bundle.hpp"
#include "core/reconstruction.hpp"
#include "core/thinnest_area.hpp"

namespace lw::core {

struct ForecastOptions {
  double window_min_days = 21.0;   ///< fit on at least the last 21 days of readings...
  double window_fraction = 0.4;    ///< ...or the last 40 % of the campaign, whichever is longer
  double band_sigmas = 2.0;        ///< band half-width in standard deviations
  double rate_uncertainty = 0.10;  ///< extra relative uncertainty of the rate (operating changes)
  double horizon_days = 1000.0;    ///< no date is reported beyond this many days after `now`
  double curve_step_days = 1.0;    ///< spacing of the published curve points
};

/// wear(t) = c0 + c1 s + c2 s^2 with s = t - t_ref (days since installation), c2 >= 0.
struct WearCurve {
  double t_ref_days = 0;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();  ///< covariance of c
  double sigma_mm = 0;                            ///< residual standard deviation (>= 1/sqrt(12))
  double rate_uncertainty = 0.10;

  double Wear(double t_days) const;
  double RateMmPerDay(double t_days) const;
  /// Standard deviation of the predicted wear (parameters plus the relative rate uncertainty).
  double Sd(double t_days) const;
};

struct CurvePoint {
  TimePoint time{};
  double thickness_mm = 0;
  double lo_mm = 0;  ///< thinner edge of the band
  double hi_mm = 0;  ///< thicker edge of the band
};

struct SensorForecast {
  std::string sensor_id;
  bool ok = false;  ///< false: too few readings; `note` says why
  std::string note;
  size_t readings_used = 0;
  TimePoint last_time{};
  double last_reading_mm = 0;  ///< the latest reading n: thickness in [n, n+1)
  double thickness_mm = 0;     ///< fitted thickness at last_time (interval centre estimate)
  double rate_mm_per_day = 0;  ///< at last_time
  std::optional<TimePoint> reach, reach_earliest, reach_latest;
  WearCurve curve;
  std::vector<CurvePoint> points;  ///< from last_time until reach_latest (or the horizon)
};

/// Fits one sensor. `readings` may hold any sensor's readings: only `sensor.id`'s are used.
SensorForecast ForecastSensor(const CrusherConfig& crusher, const SensorInfo& sensor, const std::vector<Reading>& readings,
                              const ForecastOptions& options = {});

struct RowForecast {
  std::string row;
  bool ok = false;
  std::string note;
  double min_thickness_mm = 0;     ///< the row's thinnest area now (core/thinnest_area.hpp)
  double min_thickness_lo_mm = 0;  ///< its band (map noise, quantisation, row scale)
  double min_thickness_hi_mm = 0;
  double rate_mm_per_day = 0;     ///< thinning rate of that area
  double rate_sd_mm_per_day = 0;  ///< its standard error
  std::optional<TimePoint> reach, reach_earliest, reach_latest;
  /// The area is already at or below the minimum: since when (the row's curves back in time, not
  /// before the installation); the reach dates are then empty.
  std::optional<TimePoint> below_minimum_since;
  /// Why a date is missing, in words: below minimum, a rate not distinguishable from zero, beyond
  /// the forecast horizon. Empty when every date is given.
  std::string reach_note;
  /// HoldRowForecasts kept the previously published reach date (the new estimate, reach_estimate,
  /// lies within the previous band and the previous date within the new one).
  bool reach_held = false;
  std::optional<TimePoint> reach_estimate;
  /// The sensor whose own readings set the dates (it reaches the minimum before the area's
  /// estimate does, or is past it); empty when the area's curve sets them.
  std::string reach_set_by;
};

/// Per row: the thinnest area wears `k` times its row's mean sensor wear (Eq. 9), so its curve is
/// k x the mean of the row's sensor curves. `areas` are the rows' thinnest areas (crusher.rows
/// order); `now` is the reconstruction time (latest reading used). The dates' band uses the area's
/// band as well as the curves': "earliest" starts from the thin edge of the band and wears at its
/// rate, "latest" from the thick edge. A rate whose band reaches zero gives no central or latest
/// date (it would be any date at all), only the earliest; an area below the minimum gives
/// below_minimum_since instead of dates. No row's date is later than its first sensor's own
/// (a row's thinnest area is no thicker than a sensor in it): that sensor then sets the dates
/// (reach_set_by).
std::vector<RowForecast> ForecastRows(const CrusherConfig& crusher, const std::vector<ThinnestArea>& areas,
                                      const std::vector<SensorWear>& sensor_wear, const std::vector<SensorForecast>& sensors,
                                      TimePoint now, const ForecastOptions& options = {});

/// Reline dates that hold still: each row of `current` keeps `previous`'s reach date (and its
/// below_minimum_since) while the data do not move it beyond the band: the new estimate lies within
/// the previous [earliest, latest] and the previous date within the new one. A published date then
/// changes only when the readings change it by more than its own uncertainty.
void HoldRowForecasts(const std::vector<RowForecast>& previous, std::vector<RowForecast>* current);

}  // namespace lw::core
