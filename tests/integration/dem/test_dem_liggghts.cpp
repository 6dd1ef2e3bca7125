// `linerwatch dem` end to end with the real LIGGGHTS (Debian `liggghts` + Open MPI): the tiny
// chamber of tests/data/dem/tiny is written as a case, run, stopped after its first restart file,
// resumed, and turned into a wear map that core loads; the windows add up to the map's wear.
#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "cli/cli.hpp"
#include "unit/cli/run_cli.hpp"
#include "core/wear_map.hpp"
#include "dem/runner.hpp"
#include "support/temp_directory.hpp"

#include <CppUTest/TestHarness.h>

namespace fs = std::filesystem;

namespace {

using Run = lw::test::CliRun;
Run Cli(const std::vector<std::string>& args) {
  return lw::test::RunLinerwatch(args);
}

}  // namespace

TEST_GROUP(DemLiggghts){};

TEST(DemLiggghts, CaseRunStopResumeMap) {
  lw::test::TempDirectory scratch;
  const fs::path crusher = scratch.path() / "tiny";
  const fs::path work = scratch.path() / "case";
  fs::create_directories(crusher);
  fs::copy_file(fs::path(LW_TEST_DATA_DIR) / "dem/tiny/crusher.json", crusher / "crusher.json");

  Run c = Cli({"dem", crusher.string(), "--work", work.string(), "--stage", "case"});
  LONGS_EQUAL_TEXT(0, c.code, c.err.c_str());
  CHECK(fs::exists(work / "in.crusher"));

  // Run, and stop it once the first restart file is written (as SIGINT would).
  std::atomic<bool> done{false};
  Run first;
  std::thread t([&] {
    first = Cli({"dem", crusher.string(), "--work", work.string(), "--stage", "run", "--np", "1", "--progress-every", "2"});
    done = true;
  });
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::minutes(4);
  while (!done && std::chrono::steady_clock::now() < deadline &&
         lw::dem::StepsInFolder(work / "restart", "crusher.", ".restart").empty())
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  lw::dem::RequestStop();
  t.join();
  CHECK_FALSE_TEXT(lw::dem::StepsInFolder(work / "restart", "crusher.", ".restart").empty(), first.out.c_str());
  LONGS_EQUAL_TEXT(1, first.code, (first.out + first.err).c_str());  // stopped before the end
  CHECK(first.err.find("resume") != std::string::npos);

  // Run again: it resumes from the restart file, completes, builds and installs the map.
  Run second = Cli({"dem", crusher.string(), "--work", work.string(), "--np", "1", "--install", "--progress-every", "5"});
  LONGS_EQUAL_TEXT(0, second.code, (second.out + second.err).c_str());
  CHECK_TEXT(second.out.find("resuming from restart/crusher.") != std::string::npos, second.out.c_str());
  CHECK(fs::exists(work / "log.1.liggghts"));
  CHECK(fs::exists(work / "log.2.liggghts"));

  // The mass series has no repeated or backward times across the resume.
  {
    std::ifstream in(work / "mass.txt");
    std::string line;
    double last = -1, t_s = 0;
    std::getline(in, line);  // title
    while (std::getline(in, line)) {
      std::istringstream ls(line);
      if (!(ls >> t_s)) continue;
      CHECK(t_s > last);
      last = t_s;
    }
    DOUBLES_EQUAL(3.0, last, 1e-6);
  }

  // The installed map loads and validates, with its uncertainty and stresses.
  lw::core::MapValidation v;
  const lw::core::WearMap map = lw::core::LoadWearMap(crusher / "wear_map.vtk", &v);
  LONGS_EQUAL(2 * 24 * 6, map.face_count());
  LONGS_EQUAL(0, v.degenerate_faces);
  CHECK(map.has_normal_stress());
  CHECK(map.has_shear_stress());
  CHECK(map.wear.sum() > 0);
  CHECK(map.wear.minCoeff() >= 0);
  CHECK(map.has_wear_stderr());
  CHECK(map.wear_stderr.maxCoeff() > 0);
  DOUBLES_EQUAL(0.0, map.z.minCoeff(), 0.06);  // crusher frame: z = 0 at the discharge edge
  DOUBLES_EQUAL(0.6, map.z.maxCoeff(), 0.06);

  const auto summary = nlohmann::json::parse(std::ifstream(crusher / "dem_summary.json"));
  const int k = summary["windows"]["count"].get<int>();
  CHECK(k >= 4);
  CHECK(summary["steady"]["from_s"].get<double>() > 0.5);  // detected from the mass, after filling
  LONGS_EQUAL(3, summary["rows"].size());
  CHECK(summary["liggghts"].get<std::string>().rfind("3.", 0) == 0);

  // The window increments are the map's wear, split in time.
  const lw::core::WearMap win = lw::core::LoadWearMap(crusher / "wear_windows.vtk");
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(win.face_count()));
  for (int i = 1; i <= k; ++i) {
    const auto it = win.extra.find("wear_w" + std::to_string(i));
    CHECK_TEXT(it != win.extra.end(), ("wear_w" + std::to_string(i)).c_str());
    sum += it->second;
  }
  CHECK((sum - map.wear).cwiseAbs().maxCoeff() <= 1e-6 * map.wear.cwiseAbs().maxCoeff());

  // A second map build from the same run gives the same file (deterministic post-processing).
  Run again = Cli({"dem", crusher.string(), "--work", work.string(), "--stage", "map"});
  LONGS_EQUAL_TEXT(0, again.code, again.err.c_str());
}

TEST(DemLiggghts, MapOfAnUnfinishedRunIsRefused) {
  lw::test::TempDirectory scratch;
  const fs::path crusher = scratch.path() / "tiny";
  fs::create_directories(crusher);
  fs::copy_file(fs::path(LW_TEST_DATA_DIR) / "dem/tiny/crusher.json", crusher / "crusher.json");
  LONGS_EQUAL(0, Cli({"dem", crusher.string(), "--stage", "case"}).code);
  const Run r = Cli({"dem", crusher.string(), "--stage", "map"});
  LONGS_EQUAL(1, r.code);
  CHECK_TEXT(r.err.find("not complete") != std::string::npos, r.err.c_str());
  CHECK_FALSE(fs::exists(crusher / "dem" / "wear_map.vtk"));
}
