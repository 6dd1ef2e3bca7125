#pragma once
/// Diagnosis stage 7, regions: where the refit baseline misses beyond the noise. On a scan:
/// connected cells of one sign beyond 3 sigma; at a sensor: runs of at least three events of one
/// sign beyond 3 sigma.
#include <vector>

#include "diagnosis/diagnose.hpp"
#include "stage_mismatch.hpp"
#include "stage_setup.hpp"

namespace lw::diagnosis::detail {

/// Connected cells of one sign beyond 3 sigma on scan `si` (at least two cells, or one beyond 5 sigma).
std::vector<Region> ScanRegions(const ProblemSetup& setup, const Eigen::MatrixXd& w_null, size_t si, core::TimePoint installed_at,
                                core::TimePoint scan_date);

/// Runs in time of at least three events of one sign beyond 3 sigma, per usable sensor.
std::vector<Region> SensorRegions(const ProblemSetup& setup, const NullModel& null, core::TimePoint installed_at);

/// Every region, largest mean miss first, at most 30.
std::vector<Region> FindRegions(const core::Bundle& bundle, const ProblemSetup& setup, const NullModel& null);

}  // namespace lw::diagnosis::detail
