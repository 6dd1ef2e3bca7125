// Bundle writing (core/bundle.hpp): the inverse of bundle.cpp's loaders.
#include <unistd.h>

#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "core/atomic_file.hpp"
#include "core/bundle.hpp"

namespace lw::core {
namespace fs = std::filesystem;

std::string CrusherConfigJson(const CrusherConfig& c) {
  nlohmann::json j = {{"crusher_id", c.crusher_id}};
  if (!c.site.empty()) j["site"] = c.site;
  j["installed_at"] = FormatIsoTime(c.installed_at);
  j["concave"] = {
      {"thickness_new_mm", c.thickness_new_mm}, {"thickness_min_mm", c.thickness_min_mm}, {"rows", nlohmann::json::array()}};
  for (const Row& r : c.rows) j["concave"]["rows"].push_back({{"name", r.name}, {"z_min_m", r.z_min_m}, {"z_max_m", r.z_max_m}});
  if (!c.joints_theta_deg.empty()) j["concave"]["joints_theta_deg"] = c.joints_theta_deg;
  j["sensors"] = nlohmann::json::array();
  for (const SensorInfo& s : c.sensors) {
    nlohmann::json o = {
        {"id", s.id}, {"row", s.row}, {"z_m", s.z_m}, {"theta_deg", s.theta_deg}, {"thickness_new_mm", s.thickness_new_mm}};
    if (s.address) {
      char hex[17];
      std::snprintf(hex, sizeof hex, "%016llX", static_cast<unsigned long long>(*s.address));
      o["address"] = hex;
    }
    j["sensors"].push_back(o);
  }
  return j.dump(2) + "\n";
}

std::string ReadingsCsv(const std::vector<Reading>& readings) {
  std::ostringstream r;
  r << "time,sensor_id,thickness_mm\n";
  for (const Reading& x : readings) r << FormatIsoTime(x.time) << ',' << x.sensor_id << ',' << x.thickness_mm << '\n';
  return r.str();
}

std::string OperationsCsv(const std::vector<OperationsSample>& operations) {
  bool power = false, ai = false;
  for (const OperationsSample& x : operations) {
    power = power || x.power_kw.has_value();
    ai = ai || x.ore_ai.has_value();
  }
  std::ostringstream o;
  o << "time,throughput_tph" << (power ? ",power_kw" : "") << (ai ? ",ore_ai" : "") << '\n';
  o.setf(std::ios::fixed);
  o.precision(2);
  for (const OperationsSample& x : operations) {
    o << FormatIsoTime(x.time) << ',' << x.throughput_tph;
    if (power) {
      o << ',';
      if (x.power_kw) o << *x.power_kw;
    }
    if (ai) {
      o << ',';
      if (x.ore_ai) o << *x.ore_ai;
    }
    o << '\n';
  }
  return o.str();
}

std::string ScanXyz(const Scan& scan) {
  std::ostringstream sc;
  sc.setf(std::ios::fixed);
  sc.precision(5);
  for (const auto& p : scan.points) sc << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  return sc.str();
}

std::string ScanFileName(TimePoint date) {
  return "scan_" + FormatIsoTime(date).substr(0, 10) + ".xyz";
}

void WriteBundleMap(const fs::path& path, const WearMap& map) {
  std::vector<std::pair<std::string, const Eigen::VectorXd*>> arrays = {{"wear", &map.wear}};
  if (map.has_normal_stress()) arrays.push_back({"normal_stress_average", &map.normal_stress});
  if (map.has_shear_stress()) arrays.push_back({"shear_stress_average", &map.shear_stress});
  if (map.has_wear_stderr()) arrays.push_back({"wear_stderr", &map.wear_stderr});
  WriteWearMapVtk(path, map, arrays);
}

void WriteBundle(const Bundle& b, const fs::path& dir, const std::vector<std::pair<std::string, std::string>>& extra) {
  WriteFolderAtomically(dir, [&](const fs::path& tmp) {
    WriteFileAtomically(tmp / "crusher.json", CrusherConfigJson(b.crusher));
    WriteBundleMap(tmp / "wear_map.vtk", b.map);
    WriteFileAtomically(tmp / "readings.csv", ReadingsCsv(b.readings));
    if (!b.operations.empty()) WriteFileAtomically(tmp / "operations.csv", OperationsCsv(b.operations));
    if (!b.scans.empty()) fs::create_directories(tmp / "scans");
    for (const Scan& sc : b.scans) WriteFileAtomically(tmp / "scans" / ScanFileName(sc.date), ScanXyz(sc));
    for (const auto& [name, text] : extra) WriteFileAtomically(tmp / name, text);
  });
}

}  // namespace lw::core
