// Campaign bundle loading (core::LoadBundle): crusher.json, wear_map.vtk/.csv, readings.csv,
// operations.csv and scans/*.xyz from one input. The input is a list of files, each introduced by
// a line "=== relative/path" (letters, digits, '_', '-', '.', at most one '/'); the target writes
// them into a scratch folder and loads it.
// Properties: a malformed bundle throws core::InputError only; a loaded bundle is consistent
// (readings sorted by sensor then time, every reading names a sensor of crusher.json, operations
// and scans sorted by time).
#include <algorithm>
#include <string>
#include <string_view>

#include "core/bundle.hpp"
#include "fuzz_support.hpp"

using namespace lw;
using lw::fuzz::Check;

namespace {

bool SafePath(std::string_view p) {
  if (p.empty() || p.size() > 64 || p.front() == '.' || p.front() == '/' || p.find("..") != std::string_view::npos) return false;
  if (std::count(p.begin(), p.end(), '/') > 1 || p.back() == '/') return false;
  return std::all_of(p.begin(), p.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-' || c == '.' ||
           c == '/';
  });
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view in(reinterpret_cast<const char*>(data), size);
  const std::filesystem::path dir = fuzz::ScratchDir() / "bundle";
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
  std::filesystem::create_directories(dir);
  // Split into files.
  size_t pos = in.rfind("=== ", 0) == 0 ? 0 : in.find("\n=== ");
  if (pos != std::string_view::npos && pos != 0) ++pos;
  while (pos != std::string_view::npos && pos < in.size()) {
    const size_t name_end = in.find('\n', pos);
    if (name_end == std::string_view::npos) break;
    const std::string_view name = in.substr(pos + 4, name_end - pos - 4);
    size_t next = in.find("\n=== ", name_end);
    const std::string_view body =
        in.substr(name_end + 1, next == std::string_view::npos ? std::string_view::npos : next + 1 - (name_end + 1));
    if (SafePath(name)) fuzz::WriteFile(dir / std::string(name), body);
    pos = next == std::string_view::npos ? next : next + 1;
  }
  core::Bundle b;
  try {
    b = core::LoadBundle(dir);
  } catch (const core::InputError& e) {
    Check(!e.rule().empty(), "InputError without a rule");
    return 0;
  }
  for (size_t i = 0; i < b.readings.size(); ++i) {
    Check(b.crusher.FindSensor(b.readings[i].sensor_id) != nullptr, "a reading of an unknown sensor was loaded");
    if (i) {
      const auto& p = b.readings[i - 1];
      const auto& r = b.readings[i];
      Check(p.sensor_id < r.sensor_id || (p.sensor_id == r.sensor_id && p.time <= r.time), "readings not sorted");
    }
  }
  for (size_t i = 1; i < b.operations.size(); ++i)
    Check(b.operations[i - 1].time <= b.operations[i].time, "operations not sorted");
  for (size_t i = 1; i < b.scans.size(); ++i) Check(b.scans[i - 1].date <= b.scans[i].date, "scans not sorted");
  Check(b.map.wear.size() == static_cast<Eigen::Index>(b.map.face_count()), "wear does not have one value per face");
  return 0;
}
