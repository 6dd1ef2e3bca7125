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
