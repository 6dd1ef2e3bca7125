#pragma once
/// Simulation-versus-recording diagnosis (docs/diagnosis.md, "Output"): compares a campaign's sensor readings
/// (and laser scans, if any) with the Eq. 9 reconstruction of the DEM wear map, tests whether the
/// mismatch is real, locates it, and names the physics the DEM left out by fitting a library of
/// physically parameterised wear-model changes.
///
/// Thread safety: Diagnose() is re-entrant (no global state); results are plain values.
#include <filesystem>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/bundle.hpp"
#include "core/time.hpp"

namespace lw::diagnosis {

/// Effect names, exactly as docs/diagnosis.md ("Output") spells them.
inline constexpr const char* kWorkHardening = "work_hardening";
inline constexpr const char* kHardnessGradient = "hardness_gradient";
inline constexpr const char* kSqueezeWear = "squeeze_wear";
inline constexpr const char* kProfileEvolution = "profile_evolution";
inline constexpr const char* kFeedSegregation = "feed_segregation";
inline constexpr const char* kThroughputVariation = "throughput_variation";
inline constexpr const char* kMaterialLoss = "material_loss";
inline constexpr const char* kUnexplained = "unexplained";

/// A known effect with known parameters (benchmarks only): Diagnose() then also measures how much
/// this model, with these parameters and only the row scales fitted, explains beyond the baseline
/// (DiagnosisResult::oracle). Parameter names are the fit's own (`hypotheses[].parameters`): h,
/// log_tau (work_hardening); g, d0 (hardness_gradient, d0 a share of half the thickness); beta;
/// p (profile_evolution, tilt form); v (shift form); a, b (feed_segregation: A cos, A sin); phi.
struct OracleEffect {
  std::string effect;  ///< an effect name above, or "profile_evolution:shift"
  std::map<std::string, double> parameters;
};

struct DiagnoseOptions {
  /// When set, predict every sensor's thickness (and every face's wear) at this time.
  std::optional<core::TimePoint> predict_at;
  /// Share of the sensor time span (the latest part) held out to judge fits on unseen data.
  double holdout_fraction = 0.25;
  /// Try pairs of effects (slower, needed for overlapping effects).
  bool try_pairs = true;
  /// Benchmarks: measure the true effect's model against the baseline (DiagnosisResult::oracle).
  std::optional<OracleEffect> oracle;
  /// Fit and judge the hypotheses with the noise the mismatch test learns from the residuals (each
  /// observation type's variance scale times its effective correlation, noise.mismatch_calibration)
  /// instead of the modelled noise.
  bool learned_noise_in_hypotheses = false;
  /// Look for material loss in the scans' shape (docs/diagnosis.md, "Material loss in a scan");
  /// off, only the sensors' steps show it (the benchmark's before/after).
  bool scan_craters = true;
};

/// What a known effect (DiagnoseOptions::oracle) explains beyond the baseline, with the same
/// observations, row scales refitted, under two noise models: the diagnosis' own, and the spread
/// the true model's residuals actually show (per data kind: chi-square per sensor event and per
/// scan cell of the true model; diagonal, so an upper bound where errors are correlated).
struct OracleResult {
  std::string model;
  size_t effect_params = 0;         ///< the effect's parameter count (what a fit would be charged)
  double log_n = 0;                 ///< ln(observations), the BIC charge per parameter
  double chi2_baseline = 0;         ///< refit baseline, the diagnosis' noise model
  double chi2_true = 0;             ///< the true model, row scales refitted
  double delta_chi2_sensors = 0;    ///< baseline - true, sensor events (with the per-sensor priors)
  double delta_chi2_scan = 0;       ///< baseline - true, scan cells
  double spread_sensors = 1;        ///< true model's chi-square per sensor event (empirical / modelled variance)
  double spread_sensor_priors = 1;  ///< ... per sensor intensity error (u^2 / sigma_u^2)
  double spread_scan = 1;           ///< ... per scan cell
  double delta_bic_model = 0;       ///< (delta chi2) - effect_params ln N, the diagnosis' noise
  double delta_bic_empirical =
      0;                     ///< each part's delta chi2 / its spread (events, sensor priors, scan cells), - effect_params ln N
  double min_delta_bic = 0;  ///< the diagnosis' threshold on delta BIC for a finding
};

/// Error of a model against the measurements (mm of wear depth).
struct ErrorSummary {
  double rmse_mm = 0;
  double max_abs_mm = 0;
  double holdout_rmse_mm = 0;  ///< on data the fit did not see (later readings, left-out sensors, scan sectors)
  size_t observations = 0;
  size_t holdout_observations = 0;
};

/// A located mismatch. "over": the model predicts more wear than measured.
struct Region {
  double z_min_m = 0;
  double z_max_m = 0;
  double theta_min_deg = 0;
  double theta_max_deg = 0;
  core::TimePoint from{};
  core::TimePoint to{};
  std::string sign;    ///< "over" | "under"
  double size_mm = 0;  ///< mean absolute residual over the region
  std::string source;  ///< "scan:<file>" or "sensor:<id>"
};

struct Finding {
  std::string effect;  ///< one of the k* names above
  double confidence = 0;
  std::string explanation;
  nlohmann::ordered_json parameters = nlohmann::ordered_json::object();
  nlohmann::ordered_json evidence = nlohmann::ordered_json::object();
};

/// A sensor fault (never a physics finding). Times are the fault's first and last affected reading.
struct DataQualityIssue {
  std::string sensor_id;
  std::string issue;  ///< non_physical, zero, dead, spike, flicker, thickness_up, stuck, crack, dropout, premature_step
  core::TimePoint from{};
  core::TimePoint to{};
  std::string detail;
};

/// Per configured sensor: whether the diagnosis used it (and why not), and at its latest used loop
/// crossing the Eq. 9 baseline's residual beside the noise the mismatch test allows there, part by
/// part (docs/diagnosis.md, "Reading the report": what "within the noise" means at a sensor).
/// Values NaN where not known (an excluded sensor has no residual).
struct SensorNoise {
  std::string sensor_id;
  bool used = false;
  std::string excluded_because;                           ///< empty when used: why the fit left the sensor out, in words
  double day = std::numeric_limits<double>::quiet_NaN();  ///< latest used loop crossing, days since installation
  double measured_wear_mm = std::numeric_limits<double>::quiet_NaN();
  double predicted_wear_mm = std::numeric_limits<double>::quiet_NaN();  ///< Eq. 9 baseline (JSON `baseline`)
  double residual_mm = std::numeric_limits<double>::quiet_NaN();        ///< measured - predicted: + wore more than predicted
  /// The noise model's standard deviation of that residual (mm) and its parts (each a standard
  /// deviation; noise_sd_mm^2 is the sum of their squares): the map's sampling noise at the sensor
  /// (its faces' noise through the kernel), the map's pattern error (NoiseSummary, `map_pattern_error_*`),
  /// the per-sensor floor (2 %), and the reading's own (1 mm ladder, time inside the report interval,
  /// the 2 % model floor, the events' excess scatter).
  double noise_sd_mm = std::numeric_limits<double>::quiet_NaN();
  double map_sampling_mm = std::numeric_limits<double>::quiet_NaN();
  double map_pattern_mm = std::numeric_limits<double>::quiet_NaN();
  double sensor_floor_mm = std::numeric_limits<double>::quiet_NaN();
  double reading_mm = std::numeric_limits<double>::quiet_NaN();
  std::string noise_source;  ///< the largest part: "map_pattern_error", "map_sampling_noise", "sensor_floor", "reading"
  std::string noise_detail;  ///< what that part is here, in words
  double z = std::numeric_limits<double>::quiet_NaN();  ///< residual / noise_sd
  /// The refit baseline's map-error term at the sensor (relative; what the refit absorbed there) and
  /// its prior standard deviation (relative).
  double refit_map_error_relative = std::numeric_limits<double>::quiet_NaN();
  double map_error_prior_relative = std::numeric_limits<double>::quiet_NaN();
  /// The DEM map model's own standard error of the predicted wear at the sensor (mm; core::MapModel
  /// at the sensor: its sampling noise through the kernel and its smoothing's error there), its two
  /// parts, and why it is that size here, in words with the figures (map_error_why: "sampling_noise",
  /// "edge_band", "local_structure" or "smoothing"; map_error_detail the sentence).
  double map_sd_mm = std::numeric_limits<double>::quiet_NaN();
  double map_sd_sampling_mm = std::numeric_limits<double>::quiet_NaN();
  double map_sd_smoothing_mm = std::numeric_limits<double>::quiet_NaN();
  std::string map_error_why;
  std::string map_error_detail;
  /// The residual in a sentence: its size beside the noise the test allowed (and where that comes
  /// from) and beside the map's own standard error there (and why that is its size).
  std::string explanation;
};

/// What the mismatch test's noise model says about the data (its premise). `fits`: the refit
/// baseline's chi-square per sensor event and per scan cell are not far below 1 and its excess z not
/// far below 0 (the modelled noise is not much wider than the data's scatter). `blind`: the noise is
/// as large as the wear itself (the map's pattern error, or the noise sd at the median sensor, above
/// half the predicted wear): "no mismatch" then means the test could not have seen one.
struct NoiseFit {
  bool fits = true;
  std::string detail;  ///< why it does not fit, with the figures (empty when it fits)
  bool blind = false;
  std::string blind_detail;  ///< why the test is blind, with the figures (empty when it is not)
  /// What the test could have seen: the chi-square a mismatch must add to the refit's to reach the
  /// mismatch threshold (z 4) from the z found, and that spread as a static error over the used
  /// sensors' map-error terms: in noise sd per sensor and in mm at the median sensor (NaN when not
  /// known). A static error smaller than this passes as "no mismatch".
  double chi2_to_detect = std::numeric_limits<double>::quiet_NaN();
  double detectable_sd_per_sensor = std::numeric_limits<double>::quiet_NaN();
  double detectable_mm_median_sensor = std::numeric_limits<double>::quiet_NaN();
  double median_predicted_wear_mm = std::numeric_limits<double>::quiet_NaN();
};

/// The smallest strength of an effect these data would have shown (JSON `limits`, for the effects
/// not named): from the fit's information at its noise. Under the fit's curvature the effect's main
/// parameter is estimated with standard error `stderr`; it is named when its chi-square gain
/// (parameter / stderr)^2 passes the information criterion (delta BIC > 10 with its parameters'
/// charge) and its size is more than 2 standard errors, and it is named most of the time (about
/// 84 %) when the true strength is one standard error above that.
struct DetectionLimit {
  std::string effect;     ///< EffectName
  std::string form;       ///< the form whose limit is the smallest (profile_evolution: shift or tilt)
  std::string parameter;  ///< the main parameter's name in `findings[].parameters`
  double min_detectable = std::numeric_limits<double>::quiet_NaN();
  double stderr_ = std::numeric_limits<double>::quiet_NaN();  ///< the main parameter's, inflated by the dispersion
  double z_needed = 0;                                        ///< the acceptance's bar in standard errors
  double until_day = 0;                                       ///< the data's last observation, days since installation
  bool named = false;                                         ///< a finding names this effect (the JSON then leaves it out)
  std::string sentence;                                       ///< what a planner reads
  std::string would_show_with;
};

/// The diagnosis' conclusion in words (JSON `verdict`; the report's headline; the CLI's line).
struct Verdict {
  /// "mismatch_explained", "mismatch_unexplained", "no_mismatch", "not_testable" (the noise is as
  /// large as the wear) or "noise_model_does_not_fit" (no finding, and the noise model's premise
  /// fails: then "no mismatch" says nothing about agreement).
  std::string kind;
  std::string headline;  ///< one line
  std::string detail;    ///< what it rests on and what it means for the conclusion
};

/// Per-sensor curves for the report: measured readings and the two models' thickness.
struct SensorCurve {
  std::string sensor_id;
  std::string row;
  double z_m = 0;  ///< position on the liner (crusher.json)
  double theta_deg = 0;
  double thickness_new_mm = 0;
  std::vector<double> reading_days;  ///< days since installation
  std::vector<double> reading_mm;    ///< raw readings
  std::vector<bool> reading_used;    ///< false when excluded as a fault
  std::vector<double> model_days;
  std::vector<double> baseline_thickness_mm;
  std::vector<double> improved_thickness_mm;
  bool used = true;
};

/// Residual (model - measured wear, mm) over the unwrapped liner from one scan; NaN where no data.
struct ResidualGrid {
  std::string scan_file;
  core::TimePoint date{};
  size_t nz = 0;
  size_t ntheta = 0;
  double z_min_m = 0;
  double z_max_m = 0;
  double theta_min_deg = 0;
  double theta_max_deg = 0;
  std::vector<double> measured_mm;  ///< nz * ntheta, row-major in z
  std::vector<double> before_mm;    ///< baseline (row scales refit on all data) minus measured
  std::vector<double> after_mm;     ///< improved model minus measured
};

/// One tile of the unwrapped liner for the report's maps: a map triangle, or (maps of more than
/// kMaxLinerTiles faces) a cell of a regular theta x z raster. Corners in (theta, z); a tile across
/// theta = 0 has corners above 360 (drawn twice).
struct LinerTile {
  double theta_deg[4] = {0, 0, 0, 0};
  double z_m[4] = {0, 0, 0, 0};
  int corners = 3;
};
inline constexpr size_t kMaxLinerTiles = 20000;

/// Wear per tile at one time (mm; NaN where unknown): measured (a scan, else empty) and predicted by
/// the baseline (plain Eq. 9, the JSON `baseline`) and by the improved model (with the findings).
struct LinerSnapshot {
  core::TimePoint time{};
  std::string source;  ///< "scan:<file>", or "sensors" (latest reading, no scan: sensor residuals only)
  std::vector<double> measured_mm;
  std::vector<double> baseline_mm;
  std::vector<double> improved_mm;
};

/// A thinnest point on the liner: remaining thickness with its band, where, and when.
struct ThinnestPoint {
  std::string label;  ///< what it comes from, in words
  core::TimePoint time{};
  double thickness_mm = 0;
  double lo_mm = 0;  ///< band (2 sd); lo == hi == thickness when no band is known
  double hi_mm = 0;
  double z_m = 0;
  double theta_deg = 0;
  std::string row;     ///< crusher row at z (empty outside every row)
  std::string status;  ///< reconstruction status ("ok", "unsupported", ...), empty for models
  std::string status_detail;
};

/// Per row: when its thinnest point reaches the minimum thickness (core forecast, as the live
/// dashboard shows it).
struct RelineDate {
  std::string row;
  bool ok = false;
  std::string note;
  std::optional<core::TimePoint> reach, earliest, latest;
};

/// What the HTML report draws besides the curves (docs/diagnosis.md, "Reading the report").
struct LinerReport {
  double thickness_new_mm = 0;
  double thickness_min_mm = 0;
  std::vector<LinerTile> tiles;
  bool tiles_are_faces = true;           ///< false: raster cells (large map)
  std::vector<LinerSnapshot> snapshots;  ///< one per scan, else one at the latest reading
  core::TimePoint now{};                 ///< latest reading the diagnosis used
  std::vector<double> remaining_now_mm;  ///< per tile: the live reconstruction's remaining thickness at `now`
  std::vector<ThinnestPoint> thinnest;   ///< now (reconstruction), models now, models at predict_at
  /// The thinnest area the data support now, in words (core::ThinnestAreaText of the live estimate:
  /// the dashboard's headline, what the reline dates use); empty without a live estimate.
  std::string thinnest_area;
  std::vector<RelineDate> reline;
};

struct SensorPrediction {
  std::string sensor_id;
  double baseline_thickness_mm = 0;
  double improved_thickness_mm = 0;
  /// The refit baseline's (no physics; row scales and this sensor's map-noise term fitted): what
  /// the findings add beyond recalibrating the map is the difference to `improved_thickness_mm`.
  double refit_thickness_mm = 0;
};

struct Prediction {
  core::TimePoint time{};
  std::vector<SensorPrediction> sensors;
  std::vector<double> face_wear_baseline_mm;  ///< per map face
  std::vector<double> face_wear_improved_mm;
  /// The scan the face predictions take as ground truth at its date (the latest at or before
  /// `time`; file empty when there is none or it could not be applied): each model's face wear at
  /// the scan's date is moved to the scan with the live map's weights (server, `reconstruct`), and
  /// the model carries it forward (docs/diagnosis.md, "6. Improved model and prediction").
  struct ScanAnchor {
    std::string file;
    core::TimePoint date{};
    size_t faces_measured = 0;  ///< faces with scan points (weighted against the model)
    size_t faces_filled = 0;    ///< faces without, given their neighbours' correction
    size_t sensors_used = 0;    ///< sensors with a kept reading within 2 days before the scan
    std::string detail;         ///< why the scan was not applied (empty when it was)
  } faces_scan;
};

/// What a diagnosis' "improved" model is.
enum class ImprovedModel {
  kBaseline,       ///< Eq. 9 itself (the refit below failed)
  kRefitBaseline,  ///< nothing chosen: the baseline's row scales refitted to the sensors and scans
                   ///< together, with each sensor's map-noise term; no physics added
  kFindings,       ///< the chosen model with its effects
};
/// "baseline", "refit_baseline", "findings": the JSON's `improved.model`.
const char* ImprovedModelName(ImprovedModel model);
/// The model in a report's words: "improved model (findings)", ...
const char* ImprovedModelLabel(ImprovedModel model);
/// What the model is and what its error against the recordings means, in a sentence (the JSON's
/// `improved.what`; the report's "after").
const char* ImprovedModelDescription(ImprovedModel model);

struct DiagnosisResult {
  std::string crusher_id;
  core::TimePoint installed_at{};
  ErrorSummary baseline;
  ErrorSummary improved;
  /// What `improved` and the improved predictions are (ImprovedModelName: the JSON's
  /// `improved.model`).
  ImprovedModel improved_model = ImprovedModel::kBaseline;
  bool mismatch_detected = false;
  double mismatch_z_score = 0;  ///< chi-square excess of the baseline over the noise model, in sigmas
  std::vector<Region> regions;
  std::vector<Finding> findings;
  std::vector<DataQualityIssue> data_quality;
  std::optional<Prediction> prediction;
  std::optional<OracleResult> oracle;  ///< when DiagnoseOptions::oracle was given
  std::vector<std::string> notes;      ///< skipped hypotheses and why, noise estimates
  nlohmann::ordered_json noise = nlohmann::ordered_json::object();
  nlohmann::ordered_json hypotheses = nlohmann::ordered_json::array();  ///< every model tried
  std::vector<SensorNoise> sensors;                                     ///< every configured sensor, configuration order
  NoiseFit noise_fit;
  std::vector<DetectionLimit> limits;  ///< every tested effect (JSON: those not named)
  std::vector<SensorCurve> curves;
  std::vector<ResidualGrid> grids;
  LinerReport liner;  ///< unwrapped-liner maps and the thinnest point (report only, not in the JSON)
};

/// The conclusion of `result` in words (the JSON's `verdict`, the report's headline, the CLI's line):
/// from its findings, its noise fit (NoiseFit: the premise of "no mismatch") and its sensors.
Verdict DescribeVerdict(const DiagnosisResult& result);

/// Runs the whole diagnosis on a loaded bundle. Never throws on physically odd data (faults are
/// reported). A bundle with no usable sensor readings gives a result whose note says "no usable
/// sensor readings: nothing to diagnose". Throws std::invalid_argument only when options.oracle
/// names an unknown effect or misses one of its parameters.
DiagnosisResult Diagnose(const core::Bundle& bundle, const DiagnoseOptions& options = {});

/// The JSON document of docs/diagnosis.md "Output" (plus optional extra keys).
nlohmann::ordered_json ToJson(const DiagnosisResult& result);

/// Self-contained HTML report (inline SVG, no scripts).
std::string RenderHtml(const DiagnosisResult& result);

/// Writes OUT.json-style, HTML and VTK outputs; each file goes to a temporary and is renamed.
void WriteHtml(const std::filesystem::path& path, const DiagnosisResult& result);
void WritePredictionVtk(const std::filesystem::path& path, const core::Bundle& bundle, const DiagnosisResult& result);

}  // namespace lw::diagnosis
