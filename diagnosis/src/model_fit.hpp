#pragma once
/// The diagnosis' fitting primitives, shared by its stages: the observation problem (model points,
/// time grid, observations with their noise), fits of a wear model to a subset of the observations
/// with the per-sensor intensity error profiled out, held-out scores and model evaluations.
#include <Eigen/Core>
#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include "text_format.hpp"
#include "wear_model.hpp"

namespace lw::diagnosis::detail {

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Decision thresholds (chi-square units). Calibrated on bench/diagnosis null cases.
struct Thresholds {
  double mismatch_z = 4.0;        ///< chi-square excess of the refit baseline, in sigmas, to call a mismatch real
  double min_delta_bic = 10.0;    ///< information-criterion gain over the baseline for a finding
  double min_holdout_gain = 4.0;  ///< held-out chi-square gain over the baseline
  double min_holdout_rel = 0.03;  ///< ... and as a share of the baseline's held-out chi-square
  double pair_delta_bic = 10.0;   ///< gain of a pair over its best single effect
  double min_significance = 2.0;  ///< effect size in standard errors
  double sensor_floor_mm = 0.1;   ///< loop-position tolerance of the ladder
  double scan_floor_mm = 0.2;     ///< scan registration / surface roughness floor
  double model_floor_rel =
      0.02;  ///< relative model error floor: DEM maps carry patchy, correlated error that cell averaging does not remove
  double u_floor_rel = 0.02;  ///< per-sensor intensity error floor (placement, local geometry)
};

/// `v` rounded to `digits` decimals (the JSON output's precision).
double Round(double v, double digits = 4);

/// One observation of wear: a sensor's loop-crossing event or a scan cell.
struct Obs {
  size_t point = 0;
  double t = 0;
  double wear = 0;  ///< wear minus material lost before (what the wear model explains)
  double raw = 0;   ///< wear as the sensor/scan saw it
  double sigma = 1;
  int sensor = -1;  ///< usable-sensor index, -1 for scan cells
  int scan = -1;
  int cell = -1;
  size_t j = 0;     ///< time step of `t` on the grid ...
  double frac = 0;  ///< ... and the fraction of the step after it
};

struct Problem {
  std::vector<ModelPoint> points;
  TimeGrid grid;
  std::vector<Obs> obs;
  std::vector<std::vector<size_t>> sensor_obs;  ///< per usable sensor
  std::vector<size_t> scan_obs;
  std::vector<double> sigma_u;  ///< per usable sensor
  size_t rows = 1;
  /// The map's own standard error of its first circumferential harmonic (each of the cosine and
  /// sine amplitudes, relative to the ring mean): what a feed-segregation amplitude must exceed
  /// besides the recordings' noise (MapFields::harmonic1_rel_sd).
  double map_harmonic1_sd = 0;
  /// The map's own profile error: the standard deviation of a relative intensity error shared by the
  /// scan cells of one height band (kScanBands equal bands of the concave height) in one scan
  /// (MapFields::band_rel_sd); 0: none. Profiled out like a sensor's u (ProfiledBandOffsets).
  double band_sd = 0;
};

/// Height bands of the map's profile error (Problem::band_sd).
inline constexpr int kScanBands = 8;

using Mask = std::vector<bool>;

struct FitResult {
  ModelSpec spec;
  Eigen::VectorXd x;
  double chi2 = 0;
  std::vector<double> u;     ///< per usable sensor
  Eigen::VectorXd stderr_x;  ///< standard errors from the fit's curvature, every parameter free
  /// Standard errors with the shape parameters (ParamSpec::shape) held at their fitted values; NaN
  /// for the shape parameters themselves. What tests an effect's size against zero (Significance).
  Eigen::VectorXd stderr_given_shape;
  size_t n_train = 0;
};

struct EvalOptions {
  bool use_u = true;
  bool raw = false;  ///< fit the raw wear (the baseline does not know about material loss)
};

/// A model's wear `w` (points x time steps, from Simulate) at an observation's point and time.
double Interp(const Eigen::MatrixXd& w, const Obs& o);

/// Whitened residuals over the training observations; per-sensor random intensity error u_s is
/// profiled out analytically (prior N(0, sigma_u^2)). `u_out` (optional) receives u per usable sensor;
/// `w` the simulated wear.
void Residuals(const Problem& p, const ModelSpec& spec, const Eigen::VectorXd& x, const Mask& train, const EvalOptions& opt,
               Eigen::VectorXd& r, std::vector<double>* u_out, Eigen::MatrixXd& w);

/// The (scan, height band) group of a scan observation, scan * kScanBands + band; -1 for a sensor's.
int BandIndex(const Problem& p, const Obs& o);
/// The number of (scan, height band) groups (BandIndex below it).
size_t BandCount(const Problem& p);

/// Per (scan, height band) group, over its scan cells in `mask` (`w` the model's wear, pred its value
/// at a cell): sum((pred - target) pred / sigma^2), sum(pred^2 / sigma^2), and whether it has any.
struct BandSums {
  std::vector<double> num, den;
  std::vector<bool> present;
};
BandSums SumBands(const Problem& p, const Eigen::MatrixXd& w, const Mask& mask, bool raw);

/// Each (scan, height band) group's relative offset b minimising
/// sum((pred (1 + b) - target)^2 / sigma^2) + b^2 / band_sd^2 over its scan cells in `mask`, `w` the
/// model's wear; `present[g]` is set when the mask holds cells of group g. All 0 when band_sd is 0.
std::vector<double> ProfiledBandOffsets(const Problem& p, const Eigen::MatrixXd& w, const Mask& mask, bool raw,
                                        std::vector<bool>& present);

/// For a depth-dependent model (DepthDependent): the rows of `w` of each sensor with u[s] != 0,
/// simulated at its rate times 1 + u[s] and divided by 1 + u[s], so that Interp(w, o) * (1 + u[s]) is
/// the sensor's wear on its own depth curve. Leaves `w` alone for any other model.
void SensorDepthRows(const Problem& p, const ModelSpec& spec, const Eigen::VectorXd& x, const std::vector<double>& u,
                     Eigen::MatrixXd& w);

/// Least-squares fit of `spec` on the observations in `train`, best of the `starts`.
FitResult Fit(const Problem& p, const ModelSpec& spec, const Mask& train, const EvalOptions& opt,
              const std::vector<Eigen::VectorXd>& starts, int max_iterations, double k_scale);

struct TestScore {
  double chi2 = 0;
  double sq_mm = 0;
  size_t n = 0;
};

/// Scores a fit on held-out observations. A sensor that had training data keeps its fitted
/// intensity error u; a sensor left out entirely has its u marginalised under its prior N(0, sigma_u^2)
/// (the predictive chi-square of the noise model: the map's error at an unseen sensor is noise, not
/// something a physical effect can be expected to predict). The mm error uses u = 0 there. Scan cells
/// the same way with their height band's offset (ProfiledBandOffsets): from the band's training cells,
/// else marginalised under its prior.
TestScore Score(const Problem& p, const FitResult& f, const Mask& test, const Mask& train, bool raw);

/// A hold-out split of the observations.
struct Fold {
  std::string name;
  Mask train;
  Mask test;
};

/// A model fitted on all data and on every fold's training part, with its held-out score and the
/// verdict of the hypotheses stage.
struct ModelEval {
  FitResult full;
  std::vector<FitResult> fold_fits;
  double delta_bic = 0;
  double ho_chi2 = 0;
  double ho_sq_mm = 0;
  size_t ho_n = 0;
  double ho_gain = 0;
  double ho_rel = 0;
  bool accepted = false;
  double score = 0;
  double significance = 0;  ///< smallest |effect size| / standard error over the model's effects
};

/// Standard errors from a fit's curvature `jtj` (J^T J of the whitened residuals) with the shape
/// parameters of `spec`'s effects held fixed: the inverse of the curvature restricted to the other
/// parameters; NaN for the shape parameters themselves.
Eigen::VectorXd StderrGivenShape(const ModelSpec& spec, const Eigen::MatrixXd& jtj);

/// |effect size| / standard error of an effect's main parameter in a fit (feed segregation: the
/// amplitude of its cosine). A finding needs its effect size determined by the data, not just a
/// better chi-square (two sensors can always be "explained" by a two-parameter angle pattern).
/// The standard error is the one with the shape parameters held at their fitted values: a shape
/// parameter (a time constant, an onset depth) is not identified when the size is zero, so its
/// trade-off with the size says nothing about whether the size is zero (Davies' problem of a
/// nuisance parameter present only under the alternative; the search over it is paid for by its
/// ln N in delta BIC).
double Significance(const FitResult& f, Effect e, double dispersion, double map_harmonic1_sd = 0);
/// Whether effect `e`'s size in fit `f` is pinned at the limit of its physical range (then its
/// significance is 0: the data want something this effect cannot be). `why`, when given, gets the
/// size and the range in words.
bool AtLimit(const FitResult& f, Effect e, std::string* why = nullptr);
/// The one-parameter z with the same two-sided false-alarm rate as amplitude / per-component
/// standard error `r` of a two-component (cosine, sine) amplitude, whose null law is Rayleigh:
/// P(R > r) = exp(-r^2 / 2). So every effect is held to the same 2-sd level.
double RayleighToZ(double r);

/// Start points of a fit of `spec`: row scales `k`, effect parameters seeded from earlier fits of
/// the same effects, and (unseeded) a few spread starts for the effects with several minima.
std::vector<Eigen::VectorXd> Starts(const ModelSpec& spec, const Eigen::VectorXd& k, const std::vector<const FitResult*>& seeds,
                                    double k_scale);

/// Fits `spec` on all data (starting from the refit baseline `null_fit`'s row scales and `seeds`)
/// and on every fold, and sums its held-out score over the folds.
ModelEval Evaluate(const Problem& p, const ModelSpec& spec, const std::vector<const FitResult*>& seeds, const FitResult& null_fit,
                   const std::vector<Fold>& folds, double k_scale);

/// Pearson correlation of the first min(|a|, |b|) values; 0 for fewer than 3.
double Correlation(const std::vector<double>& a, const std::vector<double>& b);

}  // namespace lw::diagnosis::detail
