#pragma once
/// Diagnosis stage 2, baseline and noise model: the Eq. 9 reconstruction (row scales, wear linear
/// in time) fitted to the sensors only, then the noise the observations carry beyond their own
/// measurement error, measured against that baseline (the map's pattern error, how many scan cells
/// share one map error), which sets each sensor's intensity prior and each scan cell's sigma.
#include <string>
#include <vector>

#include "diagnosis/diagnose.hpp"
#include "model_fit.hpp"
#include "stage_setup.hpp"

namespace lw::diagnosis::detail {

struct Baseline {
  ModelSpec spec;                    ///< row scales only
  double k_scale = 1;                ///< median wear / (intensity x time) of the sensor events: the scale of a row's k
  Mask all;                          ///< every observation
  Mask sensors_only;                 ///< the sensor events
  EvalOptions eq9_opt{false, true};  ///< raw wear, no intensity error: the Eq. 9 reconstruction
  FitResult eq9;                     ///< fitted to the sensors only
};

/// Fits the Eq. 9 baseline to the sensor events of `prob`.
Baseline FitBaseline(const Problem& prob);

struct NoiseModel {
  double map_tau = 0;          ///< relative pattern error of the smoothed map
  std::string tau_source;      ///< "scan", "sensors" or "map cross-validation"
  double corr_cells = 1;       ///< scan cells sharing one map error
  double band_sd = 0;          ///< the map's profile error used (Problem::band_sd)
  double band_sd_scan = kNaN;  ///< what the scans' band means showed (NaN: not measured)
};

/// Cells of the scan grid within one correlation area of the smoothed map's error (kernel support).
double KernelCorrelationCells(const MapFields& fields, const CellGrid& grid);
/// The map's relative pattern error: the smaller of the map's cross-validated smoothing error and
/// the excess scatter of the scan cells (else the sensors) around the baseline `w`.
NoiseModel MeasurePatternError(const ProblemSetup& setup, const Eigen::MatrixXd& w);
/// Cells sharing one error, from the scans' own residual blocks (1 when independent).
double ScanCorrelationCells(const ProblemSetup& setup, const Eigen::MatrixXd& w, double map_tau);

/// The map's profile error per (scan, eighth of the height) (Problem::band_sd): the DEM law
/// (MapFields::band_rel_sd), but no more than the scans' band means scatter about the refit baseline
/// beyond their noise (`scan_measured`, NaN when not measured); 0 without a scan.
double MeasureBandError(const ProblemSetup& setup, const Baseline& base, double* scan_measured = nullptr);

/// The whole noise model: measures it against `base` and sets `setup.prob`'s sigma_u and scan-cell sigmas.
NoiseModel CalibrateNoise(ProblemSetup& setup, const Baseline& base, DiagnosisResult& result);

/// The baseline's metrics in mm: on all observations, and held out over `folds` (refit on each
/// fold's sensor events).
ErrorSummary BaselineMetrics(const Problem& prob, const Baseline& base, const std::vector<Fold>& folds);

}  // namespace lw::diagnosis::detail
