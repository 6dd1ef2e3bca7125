// Diagnosis stage 3, hold-out folds (stage_folds.hpp).
#include "stage_folds.hpp"

#include <algorithm>
#include <limits>

namespace lw::diagnosis::detail {

std::optional<Fold> LaterReadingsFold(const Problem& prob, double holdout_fraction) {
  const size_t n_obs = prob.obs.size();
  double lo = std::numeric_limits<double>::max(), hi = 0;
  for (const Obs& o : prob.obs)
    if (o.sensor >= 0) {
      lo = std::min(lo, o.t);
      hi = std::max(hi, o.t);
    }
  const double cut = lo + (1.0 - holdout_fraction) * (hi - lo);
  Fold time{"later_readings", Mask(n_obs, false), Mask(n_obs, false)};
  size_t n_test = 0;
  // Later sensor readings are held out; scans stay in training (a scan is a spatial snapshot, tested
  // by the scan-sector fold; without it a spatial effect could not be identified in this fold).
  for (size_t i = 0; i < n_obs; ++i) {
    const bool later = prob.obs[i].sensor >= 0 && prob.obs[i].t > cut;
    (later ? time.test : time.train)[i] = true;
    if (later) ++n_test;
  }
  if (n_test < 3) return std::nullopt;
  return time;
}

std::optional<Fold> LeftOutSensorsFold(const ProblemSetup& setup) {
  const Problem& prob = setup.prob;
  const size_t n_obs = prob.obs.size();
  Fold loso{"left_out_sensors", Mask(n_obs, true), Mask(n_obs, false)};
  size_t left = 0;
  for (const std::string& row : setup.anchor_rows) {
    std::vector<const SensorData*> in_row;
    for (const SensorData& s : setup.sensors)
      if (s.usable && s.row == row) in_row.push_back(&s);
    if (in_row.size() < 2) continue;
    for (size_t k = 1; k < in_row.size(); k += 2) {
      for (size_t i : prob.sensor_obs[static_cast<size_t>(in_row[k]->usable_index)]) {
        loso.train[i] = false;
        loso.test[i] = true;
      }
      ++left;
    }
  }
  if (left == 0) return std::nullopt;
  return loso;
}

std::optional<Fold> ScanSectorsFold(const Problem& prob, const CellGrid& grid) {
  if (prob.scan_obs.empty()) return std::nullopt;
  const size_t n_obs = prob.obs.size();
  Fold sectors{"scan_sectors", Mask(n_obs, true), Mask(n_obs, false)};
  const size_t per = std::max<size_t>(1, grid.nt / 6);
  for (size_t i : prob.scan_obs) {
    const size_t it = static_cast<size_t>(prob.obs[i].cell) % grid.nt;
    const size_t iz = static_cast<size_t>(prob.obs[i].cell) / grid.nt;
    if (((it / per) + (iz * 2 / std::max<size_t>(grid.nz, 1))) % 2 == 1) {
      sectors.train[i] = false;
      sectors.test[i] = true;
    }
  }
  return sectors;
}

std::vector<Fold> BuildFolds(const ProblemSetup& setup, double holdout_fraction) {
  std::vector<Fold> folds;
  if (auto f = LaterReadingsFold(setup.prob, holdout_fraction)) folds.push_back(std::move(*f));
  if (auto f = LeftOutSensorsFold(setup)) folds.push_back(std::move(*f));
  if (auto f = ScanSectorsFold(setup.prob, setup.grid)) folds.push_back(std::move(*f));
  return folds;
}

}  // namespace lw::diagnosis::detail
