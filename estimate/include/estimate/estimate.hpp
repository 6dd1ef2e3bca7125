#pragma once
/// Live wear, one computation: Estimate(model, window, at) gives the crusher's wear (Eq. 9 from each
/// sensor's latest usable reading, the map corrected by the latest scan), its bands, the thinnest
/// areas the data support and the remaining-life forecast. The server's live wear and its
/// GET .../wear?at=TIME, `linerwatch reconstruct` and the diagnosis report's live map are this
/// function, so their numbers are one.
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/forecast.hpp"
#include "core/reconstruction.hpp"
#include "core/thinnest_area.hpp"
#include "core/time.hpp"
#include "estimate/model.hpp"
#include "estimate/window.hpp"

namespace lw::estimate {

struct EstimateOptions {
  /// A reading n means [n, n+1) mm: wear from n + 0.5; false: from n itself (the thinnest the liner
  /// can be; `linerwatch reconstruct --lower-bound`).
  bool interval_centre = true;
  bool use_scans = true;  ///< false: the map alone (`linerwatch reconstruct --no-scan`)
  bool forecast = true;   ///< false: wear only (no sensor or row forecasts)
};

struct WearEstimate {
  bool has_wear = false;     ///< a usable reading up to the time asked for
  core::TimePoint time{};    ///< latest reading used
  std::vector<Sample> used;  ///< the reading each sensor's wear came from
  std::vector<core::SensorWear> sensor_wear;
  std::vector<std::string> stale;  ///< sensors whose latest reading is too old to set a scale (core::Staleness)
  std::vector<std::string> stuck;  ///< sensors reporting one value while their row wears (core::StuckRule)
  core::Reconstruction reconstruction;
  core::ThinnestAreas areas;                ///< the thinnest areas the data support (liner, rows)
  core::SettingEstimate setting;            ///< the closed-side setting's opening by the concave's wear
  std::shared_ptr<const ScannedPlan> scan;  ///< the latest scan up to the time (nullptr: none; applied when its detail is empty)
  std::vector<core::SensorForecast> sensor_forecasts;
  std::vector<core::RowForecast> row_forecasts;
};

/// The wear of `model` from `readings` at `at`: only the usable readings (UsableForWear) up to `at`
/// and the scans up to `at`. Without `at`, now: every reading, and the newest scan even when dated
/// after the latest reading (readings arrive late; a scan is the newest measurement of the pattern).
/// With the estimate published before (`previous`), reline dates hold still within their band
/// (core::HoldRowForecasts).
WearEstimate Estimate(const CrusherModel& model, const std::vector<Sample>& readings, std::optional<core::TimePoint> at = {},
                      const EstimateOptions& options = {}, const WearEstimate* previous = nullptr);
/// The same from a window's readings (ReadingWindow::Readings()).
WearEstimate Estimate(const CrusherModel& model, const ReadingWindow& window, std::optional<core::TimePoint> at = {},
                      const EstimateOptions& options = {}, const WearEstimate* previous = nullptr);

/// A bundle's readings as samples (seq: their line in readings.csv; no flags: a bundle holds no fault readings).
/// The scan applied (`scan`, null: none) as the wear JSON's "scan" (docs/server.md): its file and
/// date, points, faces corrected, and for an earlier campaign's prior the pattern check
/// (docs/wear.md, *Earlier campaigns*); null when `scan` is.
nlohmann::ordered_json ScanJson(const CrusherModel& model, const ScannedPlan* scan);

std::vector<Sample> SamplesOf(const std::vector<core::Reading>& readings);

}  // namespace lw::estimate
