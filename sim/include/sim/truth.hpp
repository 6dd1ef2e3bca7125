#pragma once
/// The true wear that drives the virtual sensor boards of `linerwatch-sim run`.
///
/// A crusher folder written by `linerwatch-sim campaign` holds `campaign.json` (generator, seed and
/// spec): the campaign is generated again and its truth (TrueSensorThickness: every effect the
/// spec names) drives the boards. Any other crusher folder gets the map model: each sensor wears
/// linearly at a rate proportional to the map's wear intensity at its position, calibrated so the
/// sensor at the highest intensity has worn 94 % of (new - minimum) thickness after 95 days (85 mm
/// of 90 on the reference concave, the seed paper's LDWN wear).
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/bundle.hpp"
#include "sim/campaign.hpp"

namespace lw::sim {

class TruthModel {
 public:
  virtual ~TruthModel() = default;
  /// True remaining thickness (mm) of sensor `index` (crusher.json order) `day` days after
  /// installed_at.
  virtual double ThicknessMm(size_t index, double day) const = 0;
  /// One line for logs and docs: which model, with its key numbers.
  virtual std::string Describe() const = 0;
  /// Operations (tonnage) of the truth, when it has any.
  virtual std::vector<core::OperationsSample> Operations() const { return {}; }
};

/// Truth of a generated campaign.
class CampaignTruth final : public TruthModel {
 public:
  explicit CampaignTruth(Campaign campaign) : campaign_(std::move(campaign)) {}
  double ThicknessMm(size_t index, double day) const override { return campaign_.TrueSensorThickness(index, day); }
  std::string Describe() const override;
  std::vector<core::OperationsSample> Operations() const override { return campaign_.operations(); }
  const Campaign& campaign() const { return campaign_; }

 private:
  Campaign campaign_;
};

/// Linear wear proportional to the map intensity at each sensor (see the file comment).
class MapTruth final : public TruthModel {
 public:
  /// `reference_days`: the campaign length the calibration refers to (95).
  MapTruth(const core::CrusherConfig& crusher, const core::WearMap& map, double reference_days = 95,
           double reference_fraction = 0.94);
  double ThicknessMm(size_t index, double day) const override;
  std::string Describe() const override;
  double rate_mm_per_day(size_t index) const { return rate_[index]; }

 private:
  std::vector<double> new_mm_;
  std::vector<double> rate_;
  double min_mm_ = 0;
};

/// A crusher folder (docs/bundle.md: crusher.json + wear_map.vtk) ready to simulate.
struct CrusherFolder {
  std::filesystem::path dir;
  core::CrusherConfig crusher;
  std::unique_ptr<TruthModel> truth;
};

/// Loads `dir`: crusher.json, wear_map.vtk and the truth (campaign.json when present, the map
/// model otherwise). Throws std::runtime_error / core::InputError naming the file and the rule.
CrusherFolder LoadCrusherFolder(const std::filesystem::path& dir);

/// Name of the marker file `linerwatch-sim campaign` writes into a bundle.
inline constexpr const char* kCampaignMarker = "campaign.json";

}  // namespace lw::sim
