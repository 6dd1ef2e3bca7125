// Crusher folders as the server loads them (server/registry.hpp): the validation summary of a map
// made by `linerwatch dem` travels with the crusher; a broken summary is a warning, not a refusal.
#include <filesystem>
#include <fstream>

#include "server/registry.hpp"
#include "unit/server/server_fixture.hpp"

#include <CppUTest/TestHarness.h>  // last: its leak-detection macros clash with std headers

using lw::server::Registry;

TEST_GROUP(Registry){};

TEST(Registry, DemSummaryIsLoadedWithTheMap) {
  lw::test::CrusherFolder f(5, 3);
  {
    const auto c = Registry::LoadCrusher(f.folder);
    CHECK(c->dem_summary.is_null());
  }
  std::ofstream(f.folder + "/dem_summary.json") << R"({"windows": {"count": 5}, "rows": [{"row": "LDWN", "ratio": 4.2}]})";
  const auto c = Registry::LoadCrusher(f.folder);
  LONGS_EQUAL(5, c->dem_summary["windows"]["count"].get<int>());
  DOUBLES_EQUAL(4.2, c->dem_summary["rows"][0]["ratio"].get<double>(), 1e-12);
}

TEST(Registry, BrokenDemSummaryIsAWarning) {
  lw::test::CrusherFolder f(5, 4);
  std::ofstream(f.folder + "/dem_summary.json") << "{\"windows\": ";
  const auto c = Registry::LoadCrusher(f.folder);
  CHECK(c->dem_summary.is_null());
  bool warned = false;
  for (const auto& w : c->validation.warnings) warned |= w.find("dem_summary.json ignored") != std::string::npos;
  CHECK(warned);
}

// Laser scans in scans/ are projected onto the map at load; a scan that does not load is a warning
// naming the file and the rule, and the crusher is served without it.
TEST(Registry, ScansAreLoadedSortedByDateAndABrokenOneIsAWarning) {
  lw::test::CrusherFolder f(5, 3);
  const auto good = Registry::LoadCrusher(f.folder);
  LONGS_EQUAL(f.bundle.scans.size(), good->scans.size());
  CHECK(!good->scans.empty());
  CHECK(good->scans[0].faces.points_used > 0);
  CHECK(good->scans[0].scan.points.empty());  // projected, not kept
  std::ofstream(f.folder + "/scans/scan_2020-01-01.xyz") << "0.1 0.2\n";
  std::ofstream(f.folder + "/scans/notes.txt") << "not a scan\n";
  const auto c = Registry::LoadCrusher(f.folder);
  LONGS_EQUAL(good->scans.size(), c->scans.size());
  bool warned = false;
  for (const auto& w : c->validation.warnings)
    warned |=
        w.find("scans/scan_2020-01-01.xyz:1: expected three") != std::string::npos && w.find("scan ignored") != std::string::npos;
  CHECK_TEXT(warned, "no warning naming the broken scan and its line");
  // A later scan is the one live wear applies (sorted by date).
  std::filesystem::copy_file(f.folder + "/" + f.bundle.scans.back().file, f.folder + "/scans/scan_2099-01-01.xyz");
  const auto later = Registry::LoadCrusher(f.folder);
  LONGS_EQUAL(good->scans.size() + 1, later->scans.size());
  STRCMP_EQUAL("scans/scan_2099-01-01.xyz", later->scans.back().scan.file.c_str());
}

// A fleet of one crusher model shares its DEM map: the map is smoothed once, and each crusher's
// plan is the one it gets when loaded alone; a different map gets its own model.
TEST(Registry, CrushersWithTheSameMapShareItsModelAndGetTheSamePlan) {
  lw::test::CrusherFolder f(5, 3);
  lw::test::CrusherFolder other(5, 9);
  const std::string twin = f.crushers + "/twin";
  std::filesystem::create_directories(twin);
  std::filesystem::copy_file(f.folder + "/wear_map.vtk", twin + "/wear_map.vtk");
  nlohmann::json cj;
  std::ifstream(f.folder + "/crusher.json") >> cj;
  cj["crusher_id"] = "twin";
  std::ofstream(twin + "/crusher.json") << cj.dump();
  Registry::MapModels models;
  const auto a = Registry::LoadCrusher(f.folder, {}, &models);
  const auto b = Registry::LoadCrusher(twin, {}, &models);
  LONGS_EQUAL(1, models.size());
  const auto c = Registry::LoadCrusher(other.folder, {}, &models);
  LONGS_EQUAL(2, models.size());
  const auto alone = Registry::LoadCrusher(twin);
  CHECK(b->plan.model.map == &b->map);  // its own map, not the first crusher's
  DOUBLES_EQUAL(0, (alone->plan.intensity - b->plan.intensity).cwiseAbs().maxCoeff(), 0);
  DOUBLES_EQUAL(0, (alone->plan.sensor_intensity - b->plan.sensor_intensity).cwiseAbs().maxCoeff(), 0);
  DOUBLES_EQUAL(alone->plan.model.bandwidth_m, a->plan.model.bandwidth_m, 0);
  const auto c_alone = Registry::LoadCrusher(other.folder);
  DOUBLES_EQUAL(0, (c_alone->plan.intensity - c->plan.intensity).cwiseAbs().maxCoeff(), 0);
  std::vector<std::string> errors;
  const auto reg = Registry::Load(f.crushers, &errors);
  CHECK(errors.empty());
  CHECK(reg->Find("twin") != nullptr);
}

// Folders load on several threads at once: the result is the one of loading them in order. Twins
// of one map, a broken folder and two folders claiming one crusher_id (the later, by folder name,
// is refused) among eight.
TEST(Registry, LoadingFoldersInParallelGivesTheInOrderResult) {
  lw::test::CrusherFolder f(5, 3);
  nlohmann::json cj;
  std::ifstream(f.folder + "/crusher.json") >> cj;
  for (int i = 0; i < 6; ++i) {
    const std::string twin = f.crushers + "/twin" + std::to_string(i);
    std::filesystem::create_directories(twin);
    std::filesystem::copy_file(f.folder + "/wear_map.vtk", twin + "/wear_map.vtk");
    cj["crusher_id"] = i == 4 ? "twin1" : "twin" + std::to_string(i);  // twin4 claims twin1's id
    std::ofstream(twin + "/crusher.json") << cj.dump();
  }
  std::ofstream(f.crushers + "/twin2/wear_map.vtk") << "# vtk DataFile Version 3.0\nbroken\n";
  std::vector<std::string> errors;
  const auto reg = Registry::Load(f.crushers, &errors);
  LONGS_EQUAL(2, errors.size());
  CHECK_TEXT(errors[0].find("/twin2: ") != std::string::npos, errors[0].c_str());
  CHECK_TEXT(errors[1].find("/twin4: crusher_id 'twin1' is already used by another folder") != std::string::npos,
             errors[1].c_str());
  LONGS_EQUAL(5, reg->All().size());  // f's own crusher, twin0, twin1, twin3, twin5
  CHECK(reg->Find("twin2") == nullptr);
  CHECK(reg->Find("twin1")->dir.filename() == "twin1");
  const auto alone = Registry::LoadCrusher(f.crushers + "/twin5");
  DOUBLES_EQUAL(0, (alone->plan.intensity - reg->Find("twin5")->plan.intensity).cwiseAbs().maxCoeff(), 0);
}
