// Diagnosis stage 2, baseline and noise model (stage_baseline.hpp).
#include "stage_baseline.hpp"

#include <algorithm>
#include <cmath>
#include <set>

namespace lw::diagnosis::detail {
namespace {

double TrimmedMean(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t keep = v.size() - v.size() / 50;
  double sum = 0;
  for (size_t k = 0; k < keep; ++k) sum += v[k];
  return keep ? sum / static_cast<double>(keep) : 0.0;
}

// Sensors: each one's latest event (the most wear: the least relative quantisation), against
// its row's fitted scale; the fitted scales take one degree of freedom per row. Returns the
// estimate of the relative pattern error squared, NaN when too few sensors.
double SensorExcess(const ProblemSetup& setup, const Eigen::MatrixXd& w) {
  const Problem& prob = setup.prob;
  const std::vector<std::string>& anchor_rows = setup.anchor_rows;
  std::vector<double> sensor_excess;
  std::set<size_t> sensor_rows;
  for (const SensorData& sd : setup.sensors) {
    if (!sd.usable) continue;
    const auto& list = prob.sensor_obs[static_cast<size_t>(sd.usable_index)];
    if (list.empty()) continue;
    const Obs& o = prob.obs[list.back()];
    const double pred = Interp(w, o);
    if (!(pred > 2.0 * o.sigma)) continue;
    const double rs = sd.field.rel_sampling;
    sensor_excess.push_back(std::pow(o.raw / pred - 1.0, 2) - std::pow(o.sigma / pred, 2) - rs * rs);
    sensor_rows.insert(static_cast<size_t>(std::find(anchor_rows.begin(), anchor_rows.end(), sd.row) - anchor_rows.begin()));
  }
  if (sensor_excess.size() < sensor_rows.size() + 3) return kNaN;
  double sum = 0;
  for (double e : sensor_excess) sum += e;
  return sum / static_cast<double>(sensor_excess.size() - sensor_rows.size());
}

// The largest variance ratio of block means to single cells over block sizes (rows x columns of
// cells) of one scan's standardised residuals `zres` (NaN where no cell), `v1` their mean square.
double BlockVarianceRatio(const std::vector<double>& zres, double v1, const CellGrid& grid) {
  double corr_data = 1.0;
  for (size_t bz = 1; bz <= std::max<size_t>(1, grid.nz / 2); bz *= 2)
    for (size_t bt = 1; bt <= std::max<size_t>(1, grid.nt / 4); bt *= 2) {
      if (bz * bt < 2) continue;
      double sum = 0;
      size_t blocks = 0;
      for (size_t bz0 = 0; bz0 + bz <= grid.nz; bz0 += bz)
        for (size_t bt0 = 0; bt0 + bt <= grid.nt; bt0 += bt) {
          double m = 0;
          size_t c = 0;
          for (size_t iz = bz0; iz < bz0 + bz; ++iz)
            for (size_t it = bt0; it < bt0 + bt; ++it)
              if (std::isfinite(zres[iz * grid.nt + it])) {
                m += zres[iz * grid.nt + it];
                ++c;
              }
          if (2 * c < bz * bt) continue;
          sum += m * m / static_cast<double>(c);
          ++blocks;
        }
      if (blocks >= 4 && v1 > 0) corr_data = std::max(corr_data, sum / static_cast<double>(blocks) / v1);
    }
  return corr_data;
}

}  // namespace

Baseline FitBaseline(const Problem& prob) {
  Baseline b;
  const size_t n_obs = prob.obs.size();
  b.all.assign(n_obs, true);
  b.sensors_only.assign(n_obs, false);
  for (const auto& list : prob.sensor_obs)
    for (size_t i : list) b.sensors_only[i] = true;
  std::vector<double> ks;
  for (const Obs& o : prob.obs)
    if (o.sensor >= 0 && o.t > 0 && prob.points[o.point].intensity > 0)
      ks.push_back(o.raw / (prob.points[o.point].intensity * o.t));
  std::sort(ks.begin(), ks.end());
  b.k_scale = ks.empty() ? 1.0 : ks[ks.size() / 2];
  if (!(b.k_scale > 0)) b.k_scale = 1.0;
  b.spec.rows = prob.rows;
  Eigen::VectorXd k_init = Eigen::VectorXd::Constant(static_cast<Eigen::Index>(prob.rows), b.k_scale);
  b.eq9 = Fit(prob, b.spec, b.sensors_only, b.eq9_opt, {k_init}, 30, b.k_scale);
  return b;
}

double KernelCorrelationCells(const MapFields& fields, const CellGrid& grid) {
  double corr_cells = 1.0;
  const double cell_area = grid.dz * grid.dt_deg * kPi / 180.0 * fields.mean_radius_m;
  const double h = fields.model.bandwidth_m, ha = fields.model.bandwidth_arc_m;
  if (cell_area > 0 && h > 0) corr_cells = std::max(1.0, kPi * 4.0 * h * std::max(h, ha) / cell_area);
  return corr_cells;
}

NoiseModel MeasurePatternError(const ProblemSetup& setup, const Eigen::MatrixXd& w) {
  const Thresholds th;
  const Problem& prob = setup.prob;
  const std::vector<ScanCells>& scans = setup.scans;
  NoiseModel nm;
  double map_tau = setup.fields.model.smoothing_error_rel;
  std::string tau_source = "map cross-validation";
  std::vector<double> scan_excess;
  for (size_t i : prob.scan_obs) {
    const Obs& o = prob.obs[i];
    const ScanCells& sc = scans[static_cast<size_t>(o.scan)];
    const double pred = Interp(w, o);
    const double sd = sc.sigma_mm[static_cast<size_t>(o.cell)];
    if (!(pred > 2.0 * sd + th.scan_floor_mm)) continue;  // wear too small to measure a relative error
    const double rs = sc.fields[static_cast<size_t>(o.cell)].rel_sampling;
    scan_excess.push_back(std::pow((o.wear - pred) / pred, 2) - std::pow(sd / pred, 2) - rs * rs);
  }
  // Each estimate is the pattern error plus something else (the map's own structure finer than
  // any smoothing follows; a concealed effect): both are upper bounds, the smaller is used.
  double measured = kNaN;
  std::string measured_source;
  if (scan_excess.size() >= 20) {
    measured = std::sqrt(std::max(0.0, TrimmedMean(scan_excess)));
    measured_source = "scan";
  } else if (const double sensor_excess = SensorExcess(setup, w); std::isfinite(sensor_excess)) {
    measured = std::sqrt(std::max(0.0, sensor_excess));
    measured_source = "sensors";
  }
  if (std::isfinite(measured) && measured < map_tau) {
    map_tau = measured;
    tau_source = measured_source;
  }
  nm.map_tau = map_tau;
  nm.tau_source = tau_source;
  return nm;
}

double ScanCorrelationCells(const ProblemSetup& setup, const Eigen::MatrixXd& w, double map_tau) {
  const Thresholds th;
  const Problem& prob = setup.prob;
  const std::vector<ScanCells>& scans = setup.scans;
  const CellGrid& grid = setup.grid;
  double corr_data = 1.0;
  for (size_t k = 0; k < scans.size(); ++k) {
    std::vector<double> zres(grid.cells.size(), kNaN);
    double v1 = 0;
    size_t n1 = 0;
    for (size_t i : prob.scan_obs) {
      const Obs& o = prob.obs[i];
      if (static_cast<size_t>(o.scan) != k) continue;
      const double pred = std::max(Interp(w, o), 0.0);
      const double rel = std::hypot(scans[k].fields[static_cast<size_t>(o.cell)].rel_sampling, map_tau);
      const double sd = std::sqrt(std::pow(scans[k].sigma_mm[static_cast<size_t>(o.cell)], 2) + std::pow(rel * pred, 2) +
                                  th.scan_floor_mm * th.scan_floor_mm);
      const double zr = (o.wear - pred) / sd;
      zres[static_cast<size_t>(o.cell)] = zr;
      v1 += zr * zr;
      ++n1;
    }
    if (n1 < 20) continue;
    v1 /= static_cast<double>(n1);
    corr_data = std::max(corr_data, BlockVarianceRatio(zres, v1, grid));
  }
  return corr_data;
}

NoiseModel CalibrateNoise(ProblemSetup& setup, const Baseline& base, DiagnosisResult& result) {
  const Thresholds th;
  Problem& prob = setup.prob;
  // Scan-cell noise: points + map noise on the predicted wear + floors. The smoothed map's error is
  // correlated over the kernel (about (2 h)^2 pi): cells closer than that share it and are not
  // independent evidence, so the map-noise term counts once per correlation area, not per cell.
  double corr_cells = KernelCorrelationCells(setup.fields, setup.grid);
  result.noise["scan_cells_per_map_error_area"] = Round(corr_cells, 2);
  // The map's pattern error, measured: the smoothed map differs from the liner's wear beyond its
  // sampling noise (the smoothing's own bias, where real DEM maps change faster than any scale
  // follows; the DEM's physics; the chamber). Its relative size map_tau is what the observations'
  // differences from the baseline (Eq. 9 fitted to the sensors) hold beyond the map's sampling noise
  // and the measurements' own: from the scan's cells when there is a scan (dense ground truth),
  // else from the sensors' spread around their rows' scales; and the map's cross-validated
  // smoothing error (the map alone cannot tell its pattern error from its structure finer than the
  // smoothing: on real DEM maps that estimate ranged 0.14-1.0 where scans measured 0.11-0.23).
  Eigen::MatrixXd w;
  Simulate(base.spec, base.eq9.x, prob.points, prob.grid, w);
  NoiseModel nm = MeasurePatternError(setup, w);
  const double map_tau = nm.map_tau;
  result.noise["map_pattern_error_relative"] = Round(map_tau, 3);
  result.noise["map_pattern_error_source"] = nm.tau_source;
  // Each sensor's intensity error: the map's sampling noise at it and the pattern error.
  for (const SensorData& sd : setup.sensors)
    if (sd.usable)
      prob.sigma_u[static_cast<size_t>(sd.usable_index)] =
          std::sqrt(sd.field.rel_sampling * sd.field.rel_sampling + map_tau * map_tau + th.u_floor_rel * th.u_floor_rel);
  // How many scan cells share one error: the map's error is correlated over the kernel (at most
  // the kernel's support, corr_cells above), the pattern error over whatever scale it has. From
  // the scan's own residuals: b cells averaged have b times the variance of one cell's mean when
  // they share their error, 1 time when independent. The largest ratio over block sizes (rows x
  // columns of cells), bounded by the kernel's support; a concealed effect's pattern is broad and
  // raises it (cautious).
  if (!prob.scan_obs.empty()) {
    const double corr_data = ScanCorrelationCells(setup, w, map_tau);
    result.noise["scan_cells_per_map_error_area_kernel"] = Round(corr_cells, 2);
    corr_cells = std::min(corr_cells, corr_data);
    result.noise["scan_cells_per_map_error_area"] = Round(corr_cells, 2);
  }
  for (size_t i : prob.scan_obs) {
    Obs& o = prob.obs[i];
    const ScanCells& sc = setup.scans[static_cast<size_t>(o.scan)];
    const double pred = std::max(Interp(w, o), 0.0);
    const double rel = std::hypot(sc.fields[static_cast<size_t>(o.cell)].rel_sampling, map_tau);
    o.sigma = std::sqrt(std::pow(sc.sigma_mm[static_cast<size_t>(o.cell)], 2) + corr_cells * std::pow(rel * pred, 2) +
                        th.scan_floor_mm * th.scan_floor_mm + std::pow(th.model_floor_rel * pred, 2));
  }
  nm.corr_cells = corr_cells;
  nm.band_sd = MeasureBandError(setup, base, &nm.band_sd_scan);
  prob.band_sd = nm.band_sd;
  result.noise["map_band_relative_sd"] = Round(nm.band_sd);
  if (std::isfinite(nm.band_sd_scan)) result.noise["map_band_relative_sd_scan"] = Round(nm.band_sd_scan);
  return nm;
}

double MeasureBandError(const ProblemSetup& setup, const Baseline& base, double* scan_measured) {
  const Problem& prob = setup.prob;
  if (scan_measured) *scan_measured = kNaN;
  const double law = setup.fields.band_rel_sd;
  if (prob.scan_obs.empty() || !(law > 0)) return 0.0;
  // The refit baseline (row scales on sensors and scans, each sensor's u) without band offsets; each
  // (scan, band)'s offset from it, unshrunk, and that offset's variance under the noise model.
  Problem plain = prob;
  plain.band_sd = 0;
  const FitResult refit = Fit(plain, base.spec, base.all, EvalOptions{true, false}, {base.eq9.x}, 30, base.k_scale);
  Eigen::MatrixXd w;
  Simulate(base.spec, refit.x, prob.points, prob.grid, w);
  const BandSums sums = SumBands(prob, w, base.all, false);
  double excess = 0;
  size_t groups = 0;
  for (size_t g = 0; g < sums.den.size(); ++g) {
    if (!(sums.den[g] > 0)) continue;
    const double b = sums.num[g] / sums.den[g];
    excess += b * b - 1.0 / sums.den[g];
    ++groups;
  }
  // The row scales were fitted to these bands too: they took up part of the bands' scatter.
  if (groups <= prob.rows + 1) return law;
  const double measured = std::sqrt(std::max(0.0, excess / static_cast<double>(groups - prob.rows)));
  if (scan_measured) *scan_measured = measured;
  return std::min(law, measured);
}

ErrorSummary BaselineMetrics(const Problem& prob, const Baseline& base, const std::vector<Fold>& folds) {
  const size_t n_obs = prob.obs.size();
  ErrorSummary out;
  Eigen::MatrixXd w;
  Simulate(base.spec, base.eq9.x, prob.points, prob.grid, w);
  double sq = 0, mx = 0;
  for (const Obs& o : prob.obs) {
    const double e = Interp(w, o) - o.raw;
    sq += e * e;
    mx = std::max(mx, std::fabs(e));
  }
  out.rmse_mm = n_obs ? std::sqrt(sq / static_cast<double>(n_obs)) : 0;
  out.max_abs_mm = mx;
  out.observations = n_obs;
  double ho_sq = 0;
  size_t ho_n = 0;
  for (const Fold& fold : folds) {
    Mask train(n_obs, false);
    for (size_t i = 0; i < n_obs; ++i) train[i] = fold.train[i] && base.sensors_only[i];
    const FitResult ff = Fit(prob, base.spec, train, base.eq9_opt, {base.eq9.x}, 15, base.k_scale);
    const TestScore sc = Score(prob, ff, fold.test, train, true);
    ho_sq += sc.sq_mm;
    ho_n += sc.n;
  }
  out.holdout_rmse_mm = ho_n ? std::sqrt(ho_sq / static_cast<double>(ho_n)) : 0;
  out.holdout_observations = ho_n;
  return out;
}

}  // namespace lw::diagnosis::detail
