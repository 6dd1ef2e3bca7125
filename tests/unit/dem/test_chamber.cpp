// The chamber description of crusher.json (dem/chamber.hpp) and the LIGGGHTS case written from it
// (dem/case_writer.hpp): defaults for a 62-75, refusals naming the key, and the files of a case.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string>

#include "dem/case_writer.hpp"
#include "dem/chamber.hpp"
#include "support/temp_directory.hpp"

#include <CppUTest/TestHarness.h>

namespace {

nlohmann::json Crusher(const nlohmann::json& chamber) {
  nlohmann::json j = {{"crusher_id", "c1"}};
  if (!chamber.is_null()) j["chamber"] = chamber;
  return j;
}

std::string Refusal(const nlohmann::json& chamber) {
  try {
    lw::dem::ChamberFromCrusherJson(Crusher(chamber), "crusher.json");
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

std::string Read(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

size_t Count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t p = text.find(what); p != std::string::npos; p = text.find(what, p + 1)) ++n;
  return n;
}

}  // namespace

TEST_GROUP(Chamber){};

TEST(Chamber, DefaultsDescribeA6275) {
  const auto s = lw::dem::ChamberFromCrusherJson(Crusher(nullptr), "crusher.json");
  DOUBLES_EQUAL(3.0, s.height_m(), 1e-12);
  DOUBLES_EQUAL(1.15, s.concave.RadiusAt(0), 1e-12);
  DOUBLES_EQUAL(1.90, s.concave.RadiusAt(3.0), 1e-12);
  DOUBLES_EQUAL(0.19, s.closed_side_setting_m(), 1e-9);  // default CSS
  DOUBLES_EQUAL(0.25, s.open_side_setting_m(), 1e-9);    // CSS + 2 x throw
  LONGS_EQUAL(3, s.psd.size());
  CHECK(s.timestep_s <= 0.2 * s.rayleigh_time_s());
  STRCMP_EQUAL("c1", s.name.c_str());
}

TEST(Chamber, ProfilesAndCssAreRead) {
  const auto s = lw::dem::ChamberFromCrusherJson(
      Crusher({{"concave", {{"profile", {{0.0, 1.2}, {1.5, 1.5}, {3.0, 2.0}}}}}, {"css_m", 0.2}, {"eccentric_throw_m", 0.04}}),
      "crusher.json");
  DOUBLES_EQUAL(1.5, s.concave.RadiusAt(1.5), 1e-12);
  DOUBLES_EQUAL(1.75, s.concave.RadiusAt(2.25), 1e-12);
  DOUBLES_EQUAL(0.2, s.closed_side_setting_m(), 1e-9);
  // The written form reads back to the same chamber.
  nlohmann::json round = Crusher(lw::dem::ToJson(s));
  const auto again = lw::dem::ChamberFromCrusherJson(round, "case.json");
  DOUBLES_EQUAL(s.closed_side_setting_m(), again.closed_side_setting_m(), 1e-12);
  DOUBLES_EQUAL(s.concave.RadiusAt(0.7), again.concave.RadiusAt(0.7), 1e-12);
}

TEST(Chamber, RefusalsNameTheKey) {
  CHECK(Refusal({{"speed_rpm", "fast"}}).find("chamber.speed_rpm: must be a number") != std::string::npos);
  CHECK(Refusal({{"speed_rpm", -3}}).find("chamber.speed_rpm: must be between") != std::string::npos);
  CHECK(Refusal({{"colour", 1}}).find("chamber.colour: unknown key") != std::string::npos);
  CHECK(Refusal({{"psd", {{{"size_mm", 100}, {"mass_fraction", 0.5}}}}}).find("sum to") != std::string::npos);
  // A particle bigger than the closed side setting would jam a chamber without breakage.
  CHECK(Refusal({{"psd", {{{"size_mm", 250}, {"mass_fraction", 1.0}}}}}).find("closed side setting") != std::string::npos);
  CHECK(Refusal({{"timestep_s", 5e-3}}).find("Rayleigh") != std::string::npos);
  CHECK(Refusal({{"mantle", {{"r_bottom_m", 1.14}}}}).find("touches the concave") != std::string::npos);
  CHECK(Refusal({{"css_m", 0.12}}).find("closed side setting") != std::string::npos);
  CHECK(Refusal({{"concave", {{"profile", {{0.0, 1.2}, {0.0, 1.5}}}}}}).find("z must increase") != std::string::npos);
  CHECK(Refusal({{"css_m", 0.2}, {"mantle", {{"r_bottom_m", 0.9}}}}).find("not both") != std::string::npos);
  CHECK(Refusal({{"windows", 1}}).find("chamber.windows") != std::string::npos);
  CHECK(Refusal(42).find("chamber: must be an object") != std::string::npos);
}

TEST_GROUP(CaseWriter){};

TEST(CaseWriter, WritesMeshesScriptsAndClusterFiles) {
  lw::test::TempDirectory dir;
  const auto s = lw::dem::ChamberFromCrusherJson(Crusher({{"mesh_n_theta", 24}, {"mesh_n_z", 6}}), "crusher.json");
  lw::dem::WriteCase(s, dir.path());
  using L = lw::dem::CaseLayout;
  // The concave: n_theta x n_z quads, two triangles each, from z = 0 to the top edge.
  const std::string concave = Read(dir.path() / L::kConcaveStl);
  LONGS_EQUAL(2 * 24 * 6, Count(concave, "facet normal"));
  CHECK(Count(Read(dir.path() / L::kMantleStl), "facet normal") > 100);
  // The mantle starts at phase 0 of its gyration, its axis at (+throw, 0): the first vertex of the
  // mantle (theta = 0, lowest ring) lies at x = throw + r(z_bottom).
  {
    const std::string mantle = Read(dir.path() / L::kMantleStl);
    const size_t p = mantle.find("vertex ");
    double x = 0, y = 0, z = 0;
    std::istringstream(mantle.substr(p + 7)) >> x >> y >> z;
    DOUBLES_EQUAL(s.eccentric_throw_m + s.mantle.RadiusAt(z), x, 1e-6);
  }
  const std::string in = Read(dir.path() / L::kInput);
  CHECK(in.find("create_box") != std::string::npos);
  CHECK(in.find("mesh/surface/stress file concave.stl type 1 wear finnie") != std::string::npos);
  CHECK(in.find("move/mesh mesh mantle linear/variable") != std::string::npos);
  CHECK(in.find("rolling_friction epsd2") != std::string::npos);
  CHECK(in.find("insert/rate/region") != std::string::npos);
  CHECK(in.find("dump dmesh all mesh/vtk") != std::string::npos);
  CHECK(in.find("restart ") != std::string::npos);
  CHECK(in.find("file mass.txt") != std::string::npos);
  const std::string resume = Read(dir.path() / L::kResume);
  CHECK(resume.find("read_restart ${restartfile}") != std::string::npos);
  CHECK(resume.find("create_box") == std::string::npos);
  CHECK(resume.find("append mass.txt") != std::string::npos);  // a resumed run adds to the series
  CHECK(Read(dir.path() / L::kSlurm).find("#SBATCH") != std::string::npos);
  CHECK(Read(dir.path() / L::kHostfile).find("slots=") != std::string::npos);
  const auto cj = nlohmann::json::parse(Read(dir.path() / L::kCaseJson));
  LONGS_EQUAL(lw::dem::StepsOf(s).total, cj["steps"]["total"].get<long>());
  CHECK(std::filesystem::is_directory(dir.path() / L::kDumpDir));
}

TEST(CaseWriter, StepsEndOnADumpAndRestartOften) {
  const auto s = lw::dem::ChamberFromCrusherJson(Crusher({{"simulated_s", 3.1}, {"dump_interval_s", 0.5}}), "c.json");
  const auto st = lw::dem::StepsOf(s);
  LONGS_EQUAL(0, st.total % st.dump_every);
  CHECK(static_cast<double>(st.total) * s.timestep_s >= 3.1 - 1e-9);
  LONGS_EQUAL(0, st.restart_every % st.gyration);  // restarts on whole gyrations: the mantle at its STL position
  CHECK(st.total / st.restart_every >= 3);         // several chances to resume within one run
  DOUBLES_EQUAL(s.speed_rpm, 60 * st.omega_rad_s / (2 * 3.14159265358979), 0.01 * s.speed_rpm);
}
