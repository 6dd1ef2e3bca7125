// The committed libraries of real LIGGGHTS maps (data/dem/, the held-out data/dem-heldout*/ and the others in data/): every
// case's map loads as a crusher's map with its uncertainty, its crusher.json loads, the title line and the summary agree on the
// windows (>= 4), and the summary's row means are what the map holds.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "core/bundle.hpp"
#include "core/wear_map.hpp"

#include <CppUTest/TestHarness.h>

namespace fs = std::filesystem;

TEST_GROUP(DemLibrary){};

namespace {

int CheckLibrary(const fs::path& lib) {
  int cases = 0;
  for (const auto& e : fs::directory_iterator(lib)) {
    if (!e.is_directory() || !fs::exists(e.path() / "wear_map.vtk")) continue;
    ++cases;
    const std::string name = e.path().filename().string();
    const lw::core::CrusherConfig crusher = lw::core::LoadCrusherConfig(e.path() / "crusher.json");
    lw::core::MapValidation v;
    const lw::core::WearMap map = lw::core::LoadWearMap(e.path() / "wear_map.vtk", &v);
    LONGS_EQUAL_TEXT(0, v.degenerate_faces, name.c_str());
    CHECK_TEXT(map.has_normal_stress() && map.has_shear_stress(), name.c_str());
    CHECK_TEXT(map.has_wear_stderr(), name.c_str());
    CHECK_TEXT(map.wear_stderr.minCoeff() >= 0 && map.wear_stderr.maxCoeff() > 0, name.c_str());
    CHECK_TEXT(map.windows >= 4, name.c_str());

    std::ifstream in(e.path() / "wear_map.vtk");
    std::string header, title;
    std::getline(in, header);
    std::getline(in, title);
    const auto summary = nlohmann::json::parse(std::ifstream(e.path() / "dem_summary.json"));
    const int k = summary["windows"]["count"].get<int>();
    CHECK_TEXT(k >= 4, name.c_str());
    CHECK_TEXT(title.find("windows=" + std::to_string(k) + " ") != std::string::npos, title.c_str());
    CHECK_TEXT(title.find("liggghts=3.") != std::string::npos, title.c_str());
    LONGS_EQUAL_TEXT(map.face_count(), summary["faces"].get<size_t>(), name.c_str());

    // Row means recomputed from the map (area-weighted over the row's faces).
    for (const auto& r : summary["rows"]) {
      const int ri = crusher.RowIndex(r["row"].get<std::string>());
      CHECK_TEXT(ri >= 0, name.c_str());
      const auto& row = crusher.rows[static_cast<size_t>(ri)];
      double aw = 0, a = 0;
      for (Eigen::Index i = 0; i < map.wear.size(); ++i) {
        if (map.z[i] < row.z_min_m || map.z[i] >= row.z_max_m) continue;
        aw += map.areas[i] * map.wear[i], a += map.areas[i];
      }
      DOUBLES_EQUAL(r["mean_wear"].get<double>(), aw / a, 1e-6 * std::abs(aw / a));
    }

    // The window file holds K independent increments that add up to the map's wear.
    const lw::core::WearMap win = lw::core::LoadWearMap(e.path() / "wear_windows.vtk");
    Eigen::VectorXd sum = Eigen::VectorXd::Zero(map.wear.size());
    for (int w = 1; w <= k; ++w) sum += win.extra.at("wear_w" + std::to_string(w));
    CHECK_TEXT((sum - map.wear).cwiseAbs().maxCoeff() <= 1e-6 * map.wear.cwiseAbs().maxCoeff(), name.c_str());
  }
  return cases;
}

}  // namespace

TEST(DemLibrary, EveryCaseLoadsAndMatchesItsSummary) {
  CHECK(CheckLibrary(LW_DEM_LIBRARY_DIR) >= 3);
}

TEST(DemLibrary, EveryHeldOutCaseLoadsAndMatchesItsSummary) {
  CHECK(CheckLibrary(LW_DEM_HELDOUT_DIR) >= 2);
}

TEST(DemLibrary, EverySecondSetHeldOutCaseLoadsAndMatchesItsSummary) {
  CHECK(CheckLibrary(LW_DEM_HELDOUT2_DIR) >= 2);
}

// Every library in data/ (the held-out sets added later, the long run, the fine mesh): the same checks, and each library has
// a README saying what it is for.
TEST(DemLibrary, EveryLibraryInDataLoadsAndMatchesItsSummary) {
  int libraries = 0;
  for (const auto& e : fs::directory_iterator(LW_DATA_DIR)) {
    if (!e.is_directory() || e.path().filename().string().rfind("dem", 0) != 0) continue;
    ++libraries;
    CHECK_TEXT(fs::exists(e.path() / "README.md"), e.path().string().c_str());
    CHECK_TEXT(CheckLibrary(e.path()) >= 1, e.path().string().c_str());
  }
  CHECK(libraries >= 13);
}
