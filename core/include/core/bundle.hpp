#pragma once
/// Campaign bundle (docs/bundle.md): crusher.json, wear_map.vtk, readings.csv, operations.csv,
/// scans/scan_YYYY-MM-DD.xyz.
#include <Eigen/Core>
#include <filesystem>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/time.hpp"
#include "core/wear_map.hpp"

namespace lw::core {

struct Row {
  std::string name;
  double z_min_m = 0;
  double z_max_m = 0;
};

struct SensorInfo {
  std::string id;
  std::string row;
  double z_m = 0;
  double theta_deg = 0;
  double thickness_new_mm = 0;
  std::optional<uint64_t> address;  ///< radio 64-bit address
};

/// Identifiers that become MQTT topic levels, URL path segments and dashboard text (crusher, site
/// and sensor ids) keep core::IsIdentifier (core/identifier.hpp). Throws InputError naming `file`,
/// `what` and the id.
void CheckIdentifier(const std::string& id, const std::string& what, const std::string& file);

/// The slack above a sensor's as-new thickness a reading may show (one ladder loop).
inline constexpr double kReadingSlackMm = 1.0;
/// The one rule on a reading's value, shared by the server's ingest and the offline tools'
/// readings.csv: finite and in [0, the sensor's thickness_new_mm + kReadingSlackMm]. Returns the
/// rule broken, for the caller to put after the field's name ("500 is outside [0, 121] (sensor ...)"),
/// or "" when the value is one `sensor` can give.
std::string ReadingThicknessError(const SensorInfo& sensor, double thickness_mm);

/// crusher.json's optional "thinnest_area" (core/thinnest_area.hpp): the band target and the patch
/// ladder of the thinnest area the data support, and how far a sensor's reach extends.
struct ThinnestAreaConfig {
  double band_half_width_mm = 10.0;  ///< a band this narrow (half-width) supports a number
  std::vector<double> patches_m = {
      0.1, 0.2, 0.4, 0.8};  ///< area heights tried, smallest first (a square, then a ring of each); then the whole row
  /// An area whose centre lies more than half its patch plus this (surface distance, m) from every
  /// scale-setting sensor is "extrapolated" (from the DEM map alone).
  double sensor_reach_m = 0.5;
};

/// crusher.json's optional "setting" (docs/bundle.md): what the closed-side setting's drift with the
/// concave's wear is computed from (core::EstimateSetting).
struct SettingConfig {
  std::optional<double> css_mm;  ///< the closed-side setting set at installation (mm); none: the opening alone
  double ring_height_m = 0.1;    ///< height of the discharge ring at the bottom of the lowest row
};

/// One alarm rule of crusher.json's optional "alarms" (docs/alarms.md). The threshold and the
/// hysteresis are in the rule's own unit (AlarmRuleSpec): an alarm is raised past the threshold and
/// cleared only once the value is back past it by the hysteresis, so a value at the edge never flaps.
struct AlarmRule {
  bool enabled = true;
  std::string severity;   ///< "info", "warning" or "critical"
  double threshold = 0;   ///< unused by the rules without a threshold key
  double hysteresis = 0;  ///< unused by the rules without a hysteresis key
};

/// What a rule is called and which crusher.json keys set it: `alarms.NAME.THRESHOLD_KEY` etc.
struct AlarmRuleSpec {
  const char* name;
  const char* threshold_key;   ///< nullptr: the rule has no threshold
  const char* hysteresis_key;  ///< nullptr: the rule has no hysteresis
  double threshold;            ///< default (thinnest_area: above thickness_min_mm, see DefaultAlarmConfig)
  double hysteresis;
  const char* severity;
  double max;  ///< threshold and hysteresis lie in [0, max]
  /// false: off until crusher.json or REST enables it (setting_open: the operator's own limit).
  bool enabled_by_default = true;
};
/// Every rule, in the order docs/alarms.md lists them.
const std::vector<AlarmRuleSpec>& AlarmRuleSpecs();

struct AlarmConfig {
  std::vector<AlarmRule> rules;  ///< one per AlarmRuleSpecs() entry, in its order
  /// The rule named `name` (one of AlarmRuleSpecs()); throws std::out_of_range otherwise.
  const AlarmRule& Rule(const std::string& name) const;
};

/// Thicker than this (mm) is a units mistake, not a liner.
inline constexpr double kMaxThicknessMm = 1000;

struct CrusherConfig {
  std::string crusher_id;
  std::string site;  ///< optional: the MQTT site level this crusher belongs to (empty: first heard)
  TimePoint installed_at{};
  double thickness_new_mm = 0;
  double thickness_min_mm = 0;
  std::vector<Row> rows;
  /// crusher.json's optional concave.joints_theta_deg: the angles of the joints between the
  /// concave's segments (degrees in [0, 360)), where no sensor can be cast (`linerwatch plan`).
  std::vector<double> joints_theta_deg;
  std::vector<SensorInfo> sensors;
  ThinnestAreaConfig thinnest_area;
  SettingConfig setting;
  AlarmConfig alarms;  ///< crusher.json's "alarms" over DefaultAlarmConfig

  const SensorInfo* FindSensor(const std::string& id) const;
  /// Index of the row with that name, or -1.
  int RowIndex(const std::string& name) const;
  /// The earliest time a reading of this liner can have: a day before installed_at (a day's slack
  /// for clocks). An earlier reading is a previous liner's, kept in the server's history after a
  /// reline (installed_at moved on) but no part of this liner's wear, forecast or stuck rule.
  TimePoint LinerStart() const;
  /// Whether a reading of `sensor_id` (`thickness_mm` at `t`) is of this liner: from installed_at
  /// on; in the day of slack before it only when it shows no wear to speak of (at most
  /// kSlackWearMm below the sensor's as-new thickness: a liner cannot wear before it is installed,
  /// so a thinner one is the previous liner's last report); never before LinerStart().
  bool OfThisLiner(const std::string& sensor_id, TimePoint t, double thickness_mm) const;
  static constexpr double kSlackWearMm = 3.0;
};

struct Reading {
  TimePoint time{};
  std::string sensor_id;
  double thickness_mm = 0;  ///< lower bound: true thickness in [thickness_mm, thickness_mm + 1)
  size_t line = 0;          ///< line in readings.csv (0 when not from a file)
};

struct OperationsSample {
  TimePoint time{};
  double throughput_tph = 0;
  std::optional<double> power_kw;
  std::optional<double> ore_ai;
};

struct Scan {
  TimePoint date{};
  std::string file;
  std::vector<Eigen::Vector3d> points;  ///< metres, crusher frame
};

/// An earlier liner campaign of the same crusher, from a bundle's `history/NAME/` folder: its
/// crusher.json, readings.csv (optional) and scans/ (its end-of-life scan is the next liner's prior
/// for the wear pattern, estimate/model.hpp). The crusher's map is the bundle's.
struct PastCampaign {
  std::string name;  ///< the folder's name
  CrusherConfig crusher;
  std::vector<Reading> readings;  ///< sorted as Bundle::readings
  std::vector<Scan> scans;        ///< sorted by date
};

struct Bundle {
  std::filesystem::path dir;
  CrusherConfig crusher;
  WearMap map;
  MapValidation map_validation;
  std::vector<Reading> readings;             ///< sorted by (sensor_id, time); duplicates kept
  std::vector<OperationsSample> operations;  ///< sorted by time; empty when no operations.csv
  std::vector<Scan> scans;                   ///< sorted by date
  std::vector<PastCampaign> history;         ///< earlier campaigns, oldest first (installed_at)
};

/// The default rules of a crusher: thinnest_area's threshold is thickness_min_mm + the spec's 10 mm.
AlarmConfig DefaultAlarmConfig(const CrusherConfig& config);
/// An "alarms" object (crusher.json's, or a REST rule update's body) over `base`: every key
/// optional; an unknown rule or setting, a wrong type or a value out of range is refused with an
/// InputError naming `file` and the key (`alarms.battery_low.below_mv`).
AlarmConfig ParseAlarmConfig(const nlohmann::json& alarms, const AlarmConfig& base, const std::string& file);
/// The rules as the "alarms" object ParseAlarmConfig reads (every key of every rule).
nlohmann::ordered_json AlarmConfigJson(const AlarmConfig& config);

/// Parses crusher.json. Throws InputError (file, line, rule).
CrusherConfig LoadCrusherConfig(const std::filesystem::path& path);
/// crusher.json's "sensors" array into `config`'s sensors (replacing them), checked against its rows
/// as LoadCrusherConfig checks them; a sensor without thickness_new_mm takes config's. Throws
/// InputError naming `file` and the rule (a reline's new sensor layout is read by this too).
void ParseSensors(const nlohmann::json& sensors, const std::string& file, CrusherConfig* config);
/// Refuses (InputError naming `file`) rows and sensors outside the wear map's z extent.
void CheckCrusherAgainstMap(const CrusherConfig& config, const WearMap& map, const std::string& file);
/// Parses readings.csv (header time,sensor_id,thickness_mm; extra columns ignored).
std::vector<Reading> LoadReadings(const std::filesystem::path& path);
std::vector<OperationsSample> LoadOperations(const std::filesystem::path& path);
Scan LoadScan(const std::filesystem::path& path);
/// A bundle's `history/*/` folders (none: empty), each checked as a bundle's own files are, of the
/// same crusher_id as `current` and installed before it; errors name `history/NAME/FILE`.
std::vector<PastCampaign> LoadHistory(const std::filesystem::path& dir, const CrusherConfig& current, const WearMap& map);
/// A scan file's text (`x y z` in metres per line, `#` comments, blank lines): its points. Throws
/// InputError naming `file`, the line and the rule.
std::vector<Eigen::Vector3d> ParseScanPoints(const std::string& text, const std::string& file);
/// Every scans/*.xyz of a bundle or crusher folder, sorted by file name (none when there is no scans/).
std::vector<Scan> LoadScans(const std::filesystem::path& dir);

/// Loads and validates a whole bundle; readings naming unknown sensors are refused.
Bundle LoadBundle(const std::filesystem::path& dir);

// Writing: the inverse of the loaders above (docs/bundle.md). Each file is written atomically
// (core/atomic_file.hpp); what the writers write, the loaders read back.

/// crusher.json's text (site and radio addresses only when set).
std::string CrusherConfigJson(const CrusherConfig& config);
/// readings.csv: `time,sensor_id,thickness_mm`, in the order given.
std::string ReadingsCsv(const std::vector<Reading>& readings);
/// operations.csv: `time,throughput_tph` and `power_kw`, `ore_ai` when any sample has them.
std::string OperationsCsv(const std::vector<OperationsSample>& operations);
/// A scan file: one `x y z` line per point (metres, 0.01 mm resolution).
std::string ScanXyz(const Scan& scan);
/// `scan_YYYY-MM-DD.xyz`, the name the loaders date a scan by.
std::string ScanFileName(TimePoint date);
/// The map as wear_map.vtk with every per-face array it has (wear, stresses, wear_stderr).
void WriteBundleMap(const std::filesystem::path& path, const WearMap& map);

/// Writes a whole bundle (crusher.json, wear_map.vtk, readings.csv; operations.csv when there are
/// operations; scans/ when there are scans, each under ScanFileName of its date) and any `extra`
/// files (name, text) into `dir`, which must not exist or be an empty folder. The files go into a
/// temporary sibling folder renamed at the end: a reader never sees half a bundle. Throws
/// std::runtime_error naming the folder.
void WriteBundle(const Bundle& bundle, const std::filesystem::path& dir,
                 const std::vector<std::pair<std::string, std::string>>& extra = {});

}  // namespace lw::core
