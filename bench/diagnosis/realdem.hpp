#pragma once
// Benchmark generator on real DEM maps (the library of data/dem/, docs/diagnosis.md "map model"):
// each run's K steady time windows are split in two. The bundle's map is built from one part
// (wear = their sum, wear_stderr from their spread, normal stress their mean), the truth from the
// other part (independent sampling noise, the same chamber): the mean of those windows, smoothed
// heavily (a top-hat of truth_radius_frac x the concave height), is the "noise-free" wear field
// the sensors, the scan and the true wear are made from; effects go on top in the diagnosis'
// documented forms. The truth is the generator's, not the map model's (a different kernel).
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <string>
#include <tuple>
#include <vector>

#include "core/bundle.hpp"
#include "core/reconstruction.hpp"
#include "core/thinnest_area.hpp"

namespace lw::bench {

struct DemRun {
  std::string name;
  std::filesystem::path dir;
  core::CrusherConfig crusher;
  core::WearMap mesh;                     ///< wear_windows.vtk (geometry)
  std::vector<Eigen::VectorXd> wear_w;    ///< per window
  std::vector<Eigen::VectorXd> normal_w;  ///< per window (may be empty)
};

/// Every sub-folder of `dir` with wear_windows.vtk and crusher.json (sorted by name).
std::vector<DemRun> LoadDemRuns(const std::filesystem::path& dir);

struct RealDemSpec {
  uint64_t seed = 1;
  double days = 90;
  double scan_day = 70;
  double report_hours = 6;
  double truth_radius_frac = 0.12;  ///< truth smoothing radius / concave height
  /// The truth's top-hat as a local-linear fit in z (the intercept of the area-weighted line in z
  /// over the faces within the radius) instead of a plain mean: no one-sided bias at the feed and
  /// discharge edges, where the plain mean averages only faces on one side of a gradient.
  bool truth_local_linear = false;
  bool with_scan = true;
  bool with_normal = true;
  bool with_operations = false;
  double scan_noise_mm = 0.3;
  // Effects (0 = absent), forms as documented in docs/diagnosis.md.
  double hardening_h = 0, hardening_tau_days = 6;
  double gradient_g = 0, gradient_onset_mm = 15;
  double squeeze_beta = 0;
  double profile_p = 0;
  double feed_amplitude = 0, feed_theta_deg = 60;
  double throughput_phi = 0;
  std::string stuck_sensor;
  double stuck_from_day = 0;
  std::string loss_sensor;
  double loss_day = 0, loss_mm = 0;
  /// A spall anywhere on the liner (--loss-at between): from `crater_day` on, a flat-bottomed disc of
  /// `crater_radius_m` on the unwrapped surface, `crater_mm` deep, its wall 1 cm wide; scans and
  /// any sensor inside see it (0 deep: none).
  double crater_mm = 0, crater_z = 0, crater_theta_deg = 0, crater_radius_m = 0.15, crater_day = 0;
  /// Alternative effect forms (--forms alt): the same seven effects in shapes the diagnosis does not
  /// fit (what a held-out generator may use): hardening hyperbolic in time, hardness as a step at the
  /// onset, squeeze wear quadratic in normal stress, the profile changing exponentially, segregation
  /// as a 120-degree sector, throughput as a power law. For "is the right effect named, or none".
  bool alt_forms = false;
};

/// Prototype measured on the live figures, not in the product (docs/diagnosis.md, live wear): each
/// intensity of `plan` (faces and sensors) moves towards a finer kernel estimate L (Gaussian, sd
/// `hz_m` along z and `ha_m` around, kernel mean of the model's capped wear) by the empirical-Bayes
/// factor tau^2 / (tau^2 + var L): var L from the model's noise law, tau^2 (relative) the excess
/// of (L - I)^2 over var L pooled over each 0.1 m band of z (the real variation the broad estimate
/// misses there, from the map itself).
void ShrinkTowardsFinerPrototype(core::ReconstructionPlan& plan, double hz_m, double ha_m);

/// Prototype measured on the live figures, not in the product (docs/diagnosis.md, live wear): the
/// kernel scale (sd `hz` along z, `ha` around) chosen by window-split cross-validation on the map's
/// own K time windows: each window in turn is predicted by the Gaussian kernel mean of the others,
/// the squared error (area-weighted) less the part of it that comes from training on K - 1 windows
/// instead of all K (the across-window variance of the smoothed windows, which holds any spatial
/// correlation of the noise). The windows' noise is independent, so the score estimates the error of
/// the K-window smoothing against the run's own noise-free field (up to a constant). Candidates: the
/// face size x 1.4^k up to a fifth of the map's height, around 1, 3, 8 or 24 times that.
struct WindowSplitChoice {
  double hz = 0, ha = 0;
  /// (hz, ha, score relative to the chosen one) per candidate.
  std::vector<std::tuple<double, double, double>> curve;
};
WindowSplitChoice ChooseScaleByWindowSplit(const core::WearMap& map, const std::vector<Eigen::VectorXd>& windows);

/// The truth's thinnest area of the size live wear reported (`areas.liner`): its thinnest patch of
/// that size and shape in `truth_remaining` (mm per face), or its thinnest row mean when the report
/// is a whole row. What the benches compare the headline with.
double TruthThinnest(const core::ReconstructionPlan& plan, const core::ThinnestAreas& areas,
                     const Eigen::VectorXd& truth_remaining);

/// The median of the finite values of `v` (NaN when there are none): the benches' summaries, where a
/// case without an answer is NaN.
double FiniteMedian(std::vector<double> v);

class RealDemCampaign {
 public:
  RealDemCampaign(const DemRun& run, const RealDemSpec& spec);
  /// crusher.json, wear_map.vtk, readings.csv, operations.csv (when asked), scans/.
  void WriteBundle(const std::filesystem::path& dir) const;
  double TrueSensorThickness(size_t index, double day) const;
  /// True wear (mm) per face at `day`, in [0, new].
  Eigen::VectorXd TrueFaceWear(double day) const;
  /// The truth's own construction applied to the bundle's map, i.e. a second truth from the map's
  /// windows: per face the map smoothed with the truth's top-hat, per sensor (crusher order) the
  /// nearest face's value, as the truth's sensors get. Eq. 9 on these is what an estimator that knew
  /// the benchmark's smoothing would report; its error against the truth is the part of the figures
  /// the two halves' independent noise leaves, whatever the map model (docs/diagnosis.md).
  void TruthConstruction(Eigen::VectorXd& faces, Eigen::VectorXd& sensors) const;
  const core::WearMap& map() const { return map_; }
  /// The per-window wear of the windows the bundle's map sums (map_windows, in order).
  std::vector<Eigen::VectorXd> MapWindowWear() const;
  const core::CrusherConfig& crusher() const { return run_.crusher; }
  /// The truth's top-hat radius (m).
  double truth_radius_m() const { return truth_radius_m_; }
  std::vector<int> map_windows, truth_windows;

 private:
  struct Point {
    double intensity = 0, normal_tilde = 0, normal_i = 0, zn = 0, theta = 0;
  };
  double Wear(const Point& p, double day, double new_mm) const;
  /// The spall's depth (mm) at (z, theta) on day `day`, arc lengths at `radius_m`.
  double Crater(double z, double theta_deg, double radius_m, double day) const;
  double Throughput(double t) const;
  const DemRun& run_;
  RealDemSpec spec_;
  core::WearMap map_;
  std::vector<Point> faces_, sensors_;
  double rate_ = 1;
  double q_mean_ = 1;
  double normal_tilde_mean_ = 1;  ///< area mean of the truth's normal_tilde (alt squeeze form)
  double truth_radius_m_ = 0;
  std::vector<Eigen::Index> sensor_face_;  ///< per sensor: the nearest face (its truth where the smoothing reaches none)
};

}  // namespace lw::bench
