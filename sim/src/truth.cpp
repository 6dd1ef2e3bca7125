#include "sim/truth.hpp"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <stdexcept>

#include "core/reconstruction.hpp"

namespace lw::sim {

std::string CampaignTruth::Describe() const {
  std::string effects;
  for (const auto& e : campaign_.spec().effects) effects += (effects.empty() ? "" : ", ") + e.name;
  return "campaign generator truth (" + std::string(kCampaignMarker) + ": " + std::to_string(campaign_.crusher().sensors.size()) +
         " sensors, effects: " + (effects.empty() ? "none" : effects) + ")";
}

MapTruth::MapTruth(const core::CrusherConfig& crusher, const core::WearMap& map, double reference_days, double reference_fraction)
    : min_mm_(crusher.thickness_min_mm) {
  const Eigen::VectorXd intensity = core::IntensityAtSensors(crusher, map);
  const double top = intensity.size() > 0 ? intensity.maxCoeff() : 0.0;
  if (!(top > 0)) throw std::runtime_error("wear_map.vtk: the wear intensity at every sensor is zero; nothing to simulate");
  const double wear_mm = reference_fraction * (crusher.thickness_new_mm - crusher.thickness_min_mm);
  for (size_t i = 0; i < crusher.sensors.size(); ++i) {
    const double new_mm =
        crusher.sensors[i].thickness_new_mm > 0 ? crusher.sensors[i].thickness_new_mm : crusher.thickness_new_mm;
    new_mm_.push_back(new_mm);
    rate_.push_back(std::max(0.0, intensity[static_cast<Eigen::Index>(i)]) / top * wear_mm / reference_days);
  }
}

double MapTruth::ThicknessMm(size_t index, double day) const {
  return std::max(0.0, new_mm_.at(index) - rate_.at(index) * std::max(0.0, day));
}

std::string MapTruth::Describe() const {
  const double top = rate_.empty() ? 0 : *std::max_element(rate_.begin(), rate_.end());
  char buf[160];
  std::snprintf(buf, sizeof buf, "map model truth (linear wear proportional to map intensity; fastest sensor %.2f mm/day)", top);
  return buf;
}

CrusherFolder LoadCrusherFolder(const std::filesystem::path& dir) {
  namespace fs = std::filesystem;
  if (!fs::is_directory(dir)) throw std::runtime_error(dir.string() + ": not a directory");
  CrusherFolder f;
  f.dir = dir;
  f.crusher = core::LoadCrusherConfig(dir / "crusher.json");
  if (f.crusher.sensors.empty()) throw std::runtime_error((dir / "crusher.json").string() + ": no sensors to simulate");
  const fs::path marker = dir / kCampaignMarker;
  if (fs::exists(marker)) {
    std::ifstream in(marker);
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(in);
    } catch (const std::exception& e) {
      throw std::runtime_error(marker.string() + ": not valid JSON: " + e.what());
    }
    if (!j.contains("spec") || !j.contains("seed")) throw std::runtime_error(marker.string() + ": needs \"seed\" and \"spec\"");
    Campaign c = GenerateCampaign(CampaignSpec::FromJson(j["spec"]), j["seed"].get<uint64_t>());
    // The truth must describe these sensors, in this order.
    const auto& gen = c.crusher().sensors;
    bool same = gen.size() == f.crusher.sensors.size();
    for (size_t i = 0; same && i < gen.size(); ++i) same = gen[i].id == f.crusher.sensors[i].id;
    if (!same) throw std::runtime_error(marker.string() + ": its campaign's sensors differ from crusher.json's");
    f.truth = std::make_unique<CampaignTruth>(std::move(c));
  } else {
    const core::WearMap map = core::LoadWearMap(dir / "wear_map.vtk");
    f.truth = std::make_unique<MapTruth>(f.crusher, map);
  }
  return f;
}

}  // namespace lw::sim
