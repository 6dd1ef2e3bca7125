// dem::BuildMap on the tail of a real LIGGGHTS-PUBLIC 3.8 run (tests/data/dem/tiny_case: the tiny
// chamber of tests/data/dem/tiny, its mass series and its last seven concave mesh dumps).
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "core/wear_map.hpp"
#include "dem/case_writer.hpp"
#include "dem/chamber.hpp"
#include "dem/map_builder.hpp"
#include "support/temp_directory.hpp"

#include <CppUTest/TestHarness.h>

namespace fs = std::filesystem;
using namespace lw;

namespace {
const fs::path kCase = LW_DEM_CASE_DIR;

dem::ChamberSpec Spec() {
  std::ifstream in(kCase / "crusher.json");
  return dem::ChamberFromCrusherJson(nlohmann::json::parse(in), "crusher.json");
}
}  // namespace

TEST_GROUP(DemMapBuilder){};

TEST(DemMapBuilder, TheWindowsOfARealRunSumToItsMap) {
  test::TempDirectory out;
  const nlohmann::json summary = dem::BuildMap(Spec(), kCase, {}, out.path());
  const int k = summary["windows"]["count"].get<int>();
  CHECK(k >= 2);
  CHECK_EQUAL("3.8.0", summary["liggghts"].get<std::string>());
  const core::WearMap map = core::LoadWearMap(out.path() / dem::MapFiles::kMap);
  const core::WearMap win = core::LoadWearMap(out.path() / dem::MapFiles::kWindows);
  LONGS_EQUAL(288, map.face_count());
  CHECK(map.wear.sum() > 0);
  CHECK(map.has_wear_stderr() && map.wear_stderr.minCoeff() >= 0 && map.wear_stderr.maxCoeff() > 0);
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(win.face_count()));
  for (int i = 1; i <= k; ++i) sum += win.extra.at("wear_w" + std::to_string(i));
  CHECK((sum - map.wear).cwiseAbs().maxCoeff() <= 1e-6 * map.wear.cwiseAbs().maxCoeff());
}

// Found by fuzz/dem_case: a byte that is not UTF-8 in attempts.txt (or in the log's version line)
// made the summary's JSON throw nlohmann's type_error instead of writing the map.
TEST(DemMapBuilder, TextOfTheCaseThatIsNotUtf8DoesNotStopTheMap) {
  test::TempDirectory scratch;
  const fs::path dir = scratch.path() / "case";
  fs::copy(kCase, dir, fs::copy_options::recursive);
  std::ofstream(dir / "attempts.txt") << "1 0 336.8 1 compl\xf2\xff\xff\xff\n";
  const nlohmann::json summary = dem::BuildMap(Spec(), dir, {}, scratch.path() / "map");
  const std::string state = summary["attempts"][0]["state"].get<std::string>();
  CHECK_EQUAL("compl", state.substr(0, 5));
  CHECK(state.find('\xff') == std::string::npos);  // replaced (U+FFFD), not copied
  const auto written = nlohmann::json::parse(std::ifstream(scratch.path() / "map" / dem::MapFiles::kSummary));
  CHECK_EQUAL(state, written["attempts"][0]["state"].get<std::string>());
}

TEST(DemMapBuilder, ADumpThatIsNotAMeshIsRefusedNamingIt) {
  test::TempDirectory scratch;
  const fs::path dir = scratch.path() / "case";
  fs::copy(kCase, dir, fs::copy_options::recursive);
  std::ofstream(dir / "post" / "concave_10800.vtk") << "# vtk DataFile Version 5.1\nnot a mesh\n";
  try {
    dem::BuildMap(Spec(), dir, {}, scratch.path() / "map");
    FAIL("expected a refusal");
  } catch (const std::runtime_error& e) {
    CHECK_TEXT(std::string(e.what()).find("concave_10800.vtk") != std::string::npos, e.what());
  }
  CHECK_FALSE(fs::exists(scratch.path() / "map" / dem::MapFiles::kMap));
}

// Too few windows for the steady span: the refusal says how long a run would hold them, so the
// user raises chamber.simulated_s once (the c6580 chamber took two tries without it).
TEST(DemMapBuilder, TooShortARunSaysHowLongARunWouldDo) {
  test::TempDirectory out;
  const dem::ChamberSpec spec = Spec();
  try {
    dem::BuildMap(spec, kCase, {}, out.path(), 40);
    FAIL("expected a refusal");
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    const size_t at = what.find("to at least ");
    CHECK_TEXT(at != std::string::npos, e.what());
    const double need = std::stod(what.substr(at + 12));
    // 40 windows of at least one dump interval each cannot fit in the run as it is.
    CHECK_TEXT(need >= spec.simulated_s + 30 * spec.dump_interval_s, e.what());
  }
}
