// DEM wear-map import (core::ParseWearMap, the body of LoadWearMap) of arbitrary bytes as
// LW_FUZZ_MAP_FILE (wear_map.vtk or wear_map.csv; one binary per format), then the reconstruction
// plan for the fixture crusher on the imported map.
// Properties: malformed input throws core::InputError only (nothing else escapes, nothing crashes);
// an imported map is consistent (every face indexes a point, one wear value per face, finite
// geometry); PrepareReconstruction accepts it or throws InputError.
#include <cmath>
#include <exception>
#include <string>

#include "core/reconstruction.hpp"
#include "core/wear_map.hpp"
#include "fuzz_fixture.hpp"

using namespace lw;
using lw::fuzz::Check;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  core::WearMap map;
  core::MapValidation validation;
  try {
    map = core::ParseWearMap(text, LW_FUZZ_MAP_FILE, &validation);
  } catch (const core::InputError& e) {
    Check(!e.rule().empty(), "InputError without a rule");
    return 0;
  }
  const auto n = static_cast<Eigen::Index>(map.face_count());
  Check(n > 0, "a map without faces was accepted");
  Check(map.wear.size() == n, "wear does not have one value per face");
  Check(map.areas.size() == n && map.z.size() == n && map.theta_deg.size() == n, "geometry arrays do not match the faces");
  for (const auto& f : map.faces) {
    for (uint32_t v : f) Check(v < map.points.size(), "a face indexes a point that does not exist");
  }
  for (Eigen::Index i = 0; i < n; ++i) {
    Check(std::isfinite(map.wear[i]), "non-finite wear accepted");
    Check(std::isfinite(map.areas[i]) && std::isfinite(map.z[i]), "non-finite geometry from finite points");
  }
  try {
    (void)core::PrepareReconstruction(fuzz::FixtureRegistry().Find("fz1")->config, map);
  } catch (const core::InputError&) {
  }
  return 0;
}
