#pragma once
/// Campaign generator: a synthetic crusher liner campaign with a known truth, written as a bundle
/// (docs/bundle.md). The DEM-like map comes from a reduced-order chamber model (docs/sim.md); the
/// truth is that map's underlying intensity with any of the physical effects DEM leaves out, plus
/// operations, sensor readings with realistic faults, and a laser scan. Deterministic per seed.
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/bundle.hpp"

namespace lw::sim {

/// One effect DEM leaves out, by its diagnosis name, with parameters (defaults in docs/sim.md).
struct EffectSpec {
  std::string name;  ///< work_hardening, hardness_gradient, squeeze_wear, profile_evolution,
                     ///< feed_segregation, throughput_variation, material_loss
  std::map<std::string, double> params;
};

/// A sensor fault: kind = dropout | flicker | crack | stuck | dead; `day` it starts, `size`
/// (dropout: days; crack: mm; flicker: days).
struct FaultSpec {
  std::string sensor;
  std::string kind;
  double day = 0;
  double size = 0;
};

struct SensorSpec {
  std::string id;
  std::string row;
  double z_m = 0;
  double theta_deg = 0;
};

struct CampaignSpec {
  std::string crusher_id = "sim-62-75";
  std::string installed_at = "2026-01-05T00:00:00Z";
  double days = 95;  ///< length of the generated record
  double thickness_new_mm = 120;
  double thickness_min_mm = 30;
  double height_m = 3.0;    ///< concave height
  double r_bottom_m = 1.6;  ///< inner radius at the discharge (z = 0)
  double r_top_m = 2.6;     ///< inner radius at the feed opening
  int n_theta = 72;
  int n_z = 36;
  std::vector<core::Row> rows;      ///< default: LDWN, LMID, LUP thirds of the height
  std::vector<SensorSpec> sensors;  ///< default: 10 sensors (2 LUP, 4 LMID, 4 LDWN)
  double reference_wear_mm = 85;    ///< mean LDWN sensor wear at `reference_day` without effects
  double reference_day = 95;
  double dem_noise = 0.08;  ///< relative per-face DEM noise (plus a smooth component)
  double poll_minutes = 15;
  double heartbeat_hours = 6;
  double throughput_tph = 3500;
  double ore_ai = 0.35;  ///< Bond abrasion index of the ore
  std::vector<EffectSpec> effects;
  std::vector<FaultSpec> faults;
  bool write_operations = true;
  bool write_scan = true;
  double scan_day = -1;  ///< < 0: the last day
  double scan_noise_mm = 1.5;
  int scan_points = 30000;
  double scan_occluded_deg = 40;  ///< one sector the scanner could not see

  nlohmann::json ToJson() const;
  /// Reads a spec (any subset of the keys of ToJson()); throws std::invalid_argument naming the key.
  static CampaignSpec FromJson(const nlohmann::json& j);
  /// Fills rows and sensors when empty; validates ranges (std::invalid_argument naming the field).
  void Complete();
};

/// A generated campaign: the bundle's contents plus the truth.
class Campaign {
 public:
  const CampaignSpec& spec() const { return spec_; }
  const core::CrusherConfig& crusher() const { return crusher_; }
  const core::WearMap& map() const { return map_; }  ///< the DEM-like map (with DEM noise)
  const std::vector<core::Reading>& readings() const { return readings_; }
  const std::vector<core::OperationsSample>& operations() const { return operations_; }

  /// True remaining thickness (mm) of sensor `index` (crusher order) at `day` (any day, also
  /// after the generated record: the truth is integrated on demand).
  double TrueSensorThickness(size_t index, double day) const;
  /// True wear depth (mm) per map face at `day`.
  Eigen::VectorXd TrueFaceWear(double day) const;

  /// Writes the bundle atomically (temp dir + rename); refuses to overwrite a non-empty `dir`.
  void WriteBundle(const std::filesystem::path& dir) const;
  /// The truth, kept outside the bundle: spec, effects, faults, daily true sensor thickness.
  nlohmann::json TruthJson() const;

 private:
  friend Campaign GenerateCampaign(const CampaignSpec& spec, uint64_t seed);
  void Integrate(double to_day) const;

  CampaignSpec spec_;
  uint64_t seed_ = 0;
  core::CrusherConfig crusher_;
  core::WearMap map_;
  Eigen::VectorXd intensity_true_;  ///< per face, without DEM noise
  Eigen::VectorXd normal_;          ///< per face, normalised normal stress (0..1)
  Eigen::VectorXd sensor_intensity_, sensor_normal_, sensor_z_, sensor_theta_;
  std::vector<core::Reading> readings_;
  std::vector<core::OperationsSample> operations_;
  std::vector<Eigen::Vector3d> scan_;
  std::vector<double> throughput_q_;  ///< hourly wear-rate factor from tonnage x abrasiveness
  double k_mm_per_day_ = 0;
  // Integrated truth: wear per face and per sensor at every whole hour (lazily extended).
  mutable std::vector<Eigen::VectorXd> face_daily_;  // index = day
  mutable std::vector<double> sensor_hourly_flat_;   // [hour * n_sensors + s]
  mutable Eigen::VectorXd face_now_, sensor_now_;
  mutable long hours_done_ = 0;
};

Campaign GenerateCampaign(const CampaignSpec& spec, uint64_t seed);

/// Parses "name:key=value,key=value" (the CLI's --effect).
EffectSpec ParseEffect(const std::string& text);
/// Parses "sensor:kind:day[:size]" (the CLI's --fault).
FaultSpec ParseFault(const std::string& text);
/// Applies a named preset ("reference" or "paper") to a spec.
void ApplyPreset(const std::string& name, CampaignSpec* spec);

}  // namespace lw::sim
