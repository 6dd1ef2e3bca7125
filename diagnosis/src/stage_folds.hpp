#pragma once
/// Diagnosis stage 3, hold-out folds: the splits of the observations on which every model is
/// judged on data it was not fitted to.
#include <optional>
#include <vector>

#include "model_fit.hpp"
#include "stage_setup.hpp"

namespace lw::diagnosis::detail {

/// "later_readings": sensor events after the last `holdout_fraction` of the sensors' time span are
/// held out (scans stay in training); nullopt when fewer than 3 would be.
std::optional<Fold> LaterReadingsFold(const Problem& prob, double holdout_fraction);
/// "left_out_sensors": every second usable sensor of each anchored row with two or more is held out
/// entirely; nullopt when none is.
std::optional<Fold> LeftOutSensorsFold(const ProblemSetup& setup);
/// "scan_sectors": a checkerboard of scan cells (six sectors around, two halves along z) is held out;
/// nullopt without scan cells.
std::optional<Fold> ScanSectorsFold(const Problem& prob, const CellGrid& grid);

/// The folds above that exist, in that order.
std::vector<Fold> BuildFolds(const ProblemSetup& setup, double holdout_fraction);

}  // namespace lw::diagnosis::detail
