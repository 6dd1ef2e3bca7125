// `linerwatch dem --until-band` through the CLI with a stand-in LIGGGHTS (tests/fakes/fake_liggghts.cpp,
// given as --mpirun) on the tiny test chamber: it resumes for more simulated time until the band is
// within the target, printing the projection before each step; it stops at the wall-time budget
// with a clear message and the map of the run so far; bad values are refused naming the option.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>
#include <vector>

#include "core/wear_map.hpp"
#include "dem/runner.hpp"
#include "support/temp_directory.hpp"
#include "unit/cli/run_cli.hpp"

#include <CppUTest/TestHarness.h>

namespace fs = std::filesystem;

namespace {

using Run = lw::test::CliRun;

/// Every "band +/-X mm" the run printed, in order.
std::vector<double> Bands(const std::string& out) {
  std::vector<double> b;
  const std::regex re("dem: band \\+/-([0-9.]+) mm");
  for (auto it = std::sregex_iterator(out.begin(), out.end(), re); it != std::sregex_iterator(); ++it)
    b.push_back(std::stod((*it)[1].str()));
  return b;
}

size_t Count(const std::string& s, const std::string& what) {
  size_t n = 0;
  for (size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

}  // namespace

TEST_GROUP(DemUntil) {
  lw::test::TempDirectory scratch{"lw-dem-until"};
  fs::path crusher, work;
  void setup() override {
    crusher = scratch.path() / "tiny";
    work = scratch.path() / "case";
    fs::create_directories(crusher);
    fs::copy_file(fs::path(LW_TEST_DATA_DIR) / "dem/tiny/crusher.json", crusher / "crusher.json");
    unsetenv("LW_FAKE_LIGGGHTS_WALL_PER_S");
  }
  Run Dem(std::vector<std::string> extra) {
    std::vector<std::string> args = {"dem", crusher.string(), "--work", work.string(), "--mpirun", LW_FAKE_LIGGGHTS, "--np", "1"};
    args.insert(args.end(), extra.begin(), extra.end());
    return lw::test::RunLinerwatch(args);
  }
};

TEST(DemUntil, ResumesInStepsUntilTheBandIsWithinTheTarget) {
  // The band of the crusher.json run (3 s) alone, then a target a third narrower: more steps needed.
  const Run first = Dem({"--until-band", "1000"});
  LONGS_EQUAL_TEXT(0, first.code, (first.out + first.err).c_str());
  const std::vector<double> b0 = Bands(first.out);
  LONGS_EQUAL_TEXT(1, b0.size(), first.out.c_str());
  const double target = 0.66 * b0[0];
  const Run r = Dem({"--until-band", std::to_string(target), "--install"});
  LONGS_EQUAL_TEXT(0, r.code, (r.out + r.err).c_str());
  const std::vector<double> bands = Bands(r.out);
  CHECK_TEXT(bands.size() >= 2, r.out.c_str());
  CHECK_TEXT(bands.back() <= target, r.out.c_str());
  for (size_t i = 0; i + 1 < bands.size(); ++i) CHECK_TEXT(bands[i] > target, r.out.c_str());
  // Before each step: the projection and the step with its wall time; the steps resume from restarts.
  LONGS_EQUAL_TEXT(bands.size() - 1, Count(r.out, "dem: projected: "), r.out.c_str());
  LONGS_EQUAL_TEXT(bands.size() - 1, Count(r.out, "dem: next step: to "), r.out.c_str());
  CHECK_TEXT(r.out.find("resuming from restart/crusher.") != std::string::npos, r.out.c_str());
  CHECK_TEXT(r.out.find("precise enough after") != std::string::npos, r.out.c_str());
  // A projection from one step assumes 1/sqrt(T); from two or more it is measured.
  CHECK_TEXT(r.out.find("T^-0.50, the 1/sqrt(T) law") != std::string::npos, r.out.c_str());
  // The case now runs longer than crusher.json asks, and the installed map is its map.
  const auto cj = nlohmann::json::parse(std::ifstream(work / "case.json"));
  CHECK(cj["chamber"]["simulated_s"].get<double>() > 3.0 + 1e-9);
  const auto summary = nlohmann::json::parse(std::ifstream(crusher / "dem_summary.json"));
  CHECK(summary["steady"]["to_s"].get<double>() > 3.0 + 1e-9);
  CHECK(lw::core::LoadWearMap(crusher / "wear_map.vtk").has_wear_stderr());

  // Run again with the same target: the longer run is kept and already within it.
  const Run again = Dem({"--until-band", std::to_string(target)});
  LONGS_EQUAL_TEXT(0, again.code, (again.out + again.err).c_str());
  LONGS_EQUAL_TEXT(1, Bands(again.out).size(), again.out.c_str());
  CHECK_TEXT(again.out.find("already complete") != std::string::npos, again.out.c_str());
}

TEST(DemUntil, StopsAtTheBudgetWithTheMapOfTheRunSoFar) {
  // One wall second per simulated second; a budget of 7.2 s; a target no run here can reach.
  setenv("LW_FAKE_LIGGGHTS_WALL_PER_S", "1", 1);
  const Run r = Dem({"--until-band", "0.001", "--max-hours", "0.002", "--progress-every", "1"});
  unsetenv("LW_FAKE_LIGGGHTS_WALL_PER_S");
  LONGS_EQUAL_TEXT(1, r.code, (r.out + r.err).c_str());
  CHECK_TEXT(r.err.find("--max-hours 0.002: the budget is spent") != std::string::npos, r.err.c_str());
  CHECK_TEXT(r.err.find("run again with more hours") != std::string::npos, r.err.c_str());
  CHECK_TEXT(Count(r.err, "\n") == 1, r.err.c_str());
  CHECK_TEXT(r.out.find("dem: projected: ") != std::string::npos, r.out.c_str());
  // The map of the run so far is there, from more than crusher.json's 3 s; dumps and restarts are kept.
  CHECK(fs::exists(work / "wear_map.vtk"));
  const auto summary = nlohmann::json::parse(std::ifstream(work / "dem_summary.json"));
  CHECK_TEXT(summary["steady"]["to_s"].get<double>() > 3.0 + 1e-9, r.out.c_str());
  CHECK_FALSE(lw::dem::StepsInFolder(work / "restart", "crusher.", ".restart").empty());
  CHECK_FALSE(Bands(r.out).empty());
}

TEST(DemUntil, BadValuesAreRefusedNamingTheOption) {
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--until-band", "0"}, "--until-band"},
      {{"--until-band", "-2"}, "--until-band"},
      {{"--until-band", "5", "--patch", "0"}, "--patch"},
      {{"--until-band", "5", "--patch", "0.5"}, "--patch 0.500 is out of range: (0, 0.200]"},
      {{"--until-band", "5", "--max-hours", "0"}, "--max-hours"},
      {{"--until-band", "5", "--max-hours", "-1"}, "--max-hours"},
      {{"--patch", "0.1"}, "--patch and --max-hours go with --until-band"},
      {{"--until-band", "5", "--stage", "run"}, "--until-band"},
  };
  for (const auto& [extra, needle] : cases) {
    const Run r = Dem(extra);
    LONGS_EQUAL_TEXT(2, r.code, (needle + ": " + r.out + r.err).c_str());
    CHECK_TEXT(r.err.find(needle) != std::string::npos, r.err.c_str());
    CHECK_TEXT(r.out.empty(), r.out.c_str());
  }
  CHECK_FALSE(fs::exists(work));  // refused before anything was written
}
