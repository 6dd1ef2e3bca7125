// The `linerwatch` CLI through its library entry point: help, bad input (non-zero, one line, no
// output file), diagnose outputs (JSON keys, HTML, prediction VTK), --config equivalence.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "cli/cli.hpp"
#include "unit/cli/run_cli.hpp"
#include "core/angles.hpp"
#include "core/bundle.hpp"
#include "core/reconstruction.hpp"
#include "core/thinnest_area.hpp"
#include "support/temp_directory.hpp"
#include "unit/core/bundle_fixture.hpp"
#include "unit/diagnosis/synthetic_bundle.hpp"

// CppUTest last: its leak-detector macros redefine new.
#include <CppUTest/TestHarness.h>

namespace fs = std::filesystem;

namespace {

using Run = lw::test::CliRun;
Run Cli(const std::vector<std::string>& args) {
  return lw::test::RunLinerwatch(args);
}

bool OneLine(const std::string& s) {
  return !s.empty() && s.find('\n') == s.size() - 1;
}

std::string Slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

TEST_GROUP(Linerwatch) {
  lw::test::TempDirectory tmp{"lw-cli"};
  const fs::path& dir = tmp.path();
  fs::path Bundle(const lw::test::SyntheticSpec& spec = {}) {
    const fs::path b = dir / "bundle";
    lw::test::WriteSyntheticBundle(b, spec);
    return b;
  }
  // `reconstruct` on bundle folder `b` names `sensor` under `heading` and in its JSON's `key`, and
  // equals the live wear of `bundle` (as written, before the change) without that sensor's readings.
  void CheckReconstructLeavesOut(const fs::path& b, lw::core::Bundle bundle, const std::string& sensor, const char* heading,
                                 const char* key) {
    std::erase_if(bundle.readings, [&](const lw::core::Reading& r) { return r.sensor_id == sensor; });
    const Run a = Cli({"reconstruct", b.string(), "--no-scan", "--json", (dir / "a.json").string()});
    LONGS_EQUAL(0, a.code);
    CHECK_TEXT(a.out.find(heading) != std::string::npos && a.out.find(sensor) != std::string::npos, a.out.c_str());
    const auto j = nlohmann::json::parse(Slurp(dir / "a.json"));
    CHECK_TEXT(j[key] == nlohmann::json::array({sensor}), j[key].dump().c_str());
    const auto without = lw::core::Reconstruct(
        bundle.crusher, bundle.map, lw::core::SensorWearAt(bundle.crusher, bundle.readings, lw::core::TimePoint::max()));
    DOUBLES_EQUAL(without.min_thickness_mm, j["min_thickness_mm"].get<double>(), 1e-9);
  }
};

// `reconstruct` leads with the thinnest area the data support (core::FindThinnestAreas, as the
// server's wear), at the liner and per row, in words and in its JSON.
TEST(Linerwatch, ReconstructReportsTheThinnestAreaTheServerReports) {
  const fs::path b = Bundle();
  const Run r = Cli({"reconstruct", b.string(), "--no-scan", "--json", (dir / "t.json").string()});
  LONGS_EQUAL_TEXT(0, r.code, r.err.c_str());
  CHECK_TEXT(r.out.find("thinnest area (") != std::string::npos, r.out.c_str());
  const auto j = nlohmann::json::parse(Slurp(dir / "t.json"));
  const lw::core::Bundle bundle = lw::core::LoadBundle(b);
  const lw::core::ReconstructionPlan plan = lw::core::PrepareReconstruction(bundle.crusher, bundle.map);
  const std::vector<size_t> live = lw::core::LiveReadingIndices(bundle.crusher, bundle.readings, lw::core::TimePoint::max());
  std::vector<lw::core::Reading> used;
  for (const size_t i : live) used.push_back(bundle.readings[i]);
  const lw::core::ThinnestAreas want = lw::core::FindThinnestAreas(
      plan, lw::core::Reconstruct(plan, lw::core::SensorWearFrom(bundle.crusher, bundle.readings, live)), used);
  CHECK(j["thinnest_area"] == nlohmann::json::parse(lw::core::ThinnestAreaJson(want.liner).dump()));
  LONGS_EQUAL(want.rows.size(), j["rows"].size());
  for (size_t k = 0; k < want.rows.size(); ++k)
    CHECK(j["rows"][k]["thinnest_area"] == nlohmann::json::parse(lw::core::ThinnestAreaJson(want.rows[k]).dump()));
  CHECK_FALSE(j.contains("worn_through_faces"));
  CHECK(r.out.find(lw::core::ThinnestAreaText(want.liner)) != std::string::npos);
}

TEST(Linerwatch, HelpExitsZero) {
  const Run r = Cli({"--help"});
  LONGS_EQUAL(0, r.code);
  CHECK_TRUE(r.out.find("diagnose BUNDLE --json") != std::string::npos);
  LONGS_EQUAL(0, Cli({"diagnose", "--help"}).code);
}

TEST(Linerwatch, MissingBundleIsOneLineErrorAndNoOutput) {
  const fs::path out = dir / "out.json";
  const Run r = Cli({"diagnose", (dir / "nope").string(), "--json", out.string()});
  CHECK_TRUE(r.code != 0);
  CHECK_TRUE(OneLine(r.err));
  CHECK_TRUE(r.err.find("nope") != std::string::npos);
  CHECK_FALSE(fs::exists(out));
}

// Found by fuzz/ in the other programs' config readers: nlohmann throws out_of_range, not
// parse_error, for a number beyond double range; it must be a one-line bad-input error here too.
TEST(Linerwatch, ConfigNumberBeyondDoubleRangeIsOneLineError) {
  const fs::path cfg = dir / "overflow.json";
  std::ofstream(cfg) << "{\"windows\": 1e999}";
  const Run r = Cli({"dem", (dir / "nope").string(), "--config", cfg.string()});
  LONGS_EQUAL(1, r.code);
  CHECK_TRUE(OneLine(r.err));
  CHECK_TEXT(r.err.find("overflow.json: invalid JSON") != std::string::npos, r.err.c_str());
}

TEST(Linerwatch, BadReadingNamesFileAndLineAndWritesNothing) {
  const fs::path b = Bundle();
  {
    std::ofstream f(b / "readings.csv");
    f << "time,sensor_id,thickness_mm\n2024-01-02T00:00:00Z,LDWN-1,99\nyesterday,LDWN-1,98\n";
  }
  const fs::path out = dir / "out.json";
  const Run r = Cli({"diagnose", b.string(), "--json", out.string()});
  CHECK_TRUE(r.code != 0);
  CHECK_TRUE(OneLine(r.err));
  CHECK_TRUE(r.err.find("readings.csv") != std::string::npos);
  CHECK_TRUE(r.err.find(":3") != std::string::npos);
  CHECK_FALSE(fs::exists(out));
}

TEST(Linerwatch, UsageErrorsAreRefusedBeforeAnyWork) {
  const fs::path b = Bundle();
  const fs::path out = dir / "out.json";
  Run r = Cli({"diagnose", b.string()});
  CHECK_TRUE(r.code != 0);
  CHECK_TRUE(OneLine(r.err));
  r = Cli({"diagnose", b.string(), "--json", out.string(), "--predict-vtk", (dir / "x.vtk").string()});
  CHECK_TRUE(r.code != 0);
  CHECK_TRUE(r.err.find("--predict-at") != std::string::npos);
  r = Cli({"diagnose", b.string(), "--json", out.string(), "--predict-at", "someday"});
  CHECK_TRUE(r.code != 0);
  r = Cli({"diagnose", b.string(), "--json", out.string(), "--bogus"});
  CHECK_TRUE(r.code != 0);
  r = Cli({"frobnicate"});
  CHECK_TRUE(r.code != 0);
  CHECK_FALSE(fs::exists(out));
  CHECK_FALSE(fs::exists(dir / "x.vtk"));
}

TEST(Linerwatch, DiagnoseWritesJsonHtmlAndPredictionVtkFromConfig) {
  lw::test::SyntheticSpec spec;
  spec.feed_amplitude = 0.25;
  const fs::path b = Bundle(spec);
  const fs::path json = dir / "d.json", html = dir / "d.html", vtk = dir / "p.vtk", cfg = dir / "cfg.json";
  {
    std::ofstream c(cfg);
    c << "{\"bundle\": \"" << b.string() << "\", \"json\": \"" << json.string() << "\", \"html\": \"" << html.string()
      << "\", \"predict-at\": \"2024-04-20\", \"predict_vtk\": \"" << vtk.string() << "\", \"no_pairs\": true}";
  }
  const Run r = Cli({"diagnose", "--config", cfg.string()});
  LONGS_EQUAL(0, r.code);
  const auto j = nlohmann::json::parse(Slurp(json));
  for (const char* key : {"baseline", "mismatch", "findings", "improved", "data_quality", "prediction"})
    CHECK_TRUE(j.contains(key));
  STRCMP_EQUAL("feed_segregation", j["findings"][0]["effect"].get<std::string>().c_str());
  // The line printed is the JSON's verdict (what was found, or what was not tested), not a bare
  // "mismatch (not) detected".
  STRCMP_EQUAL("mismatch_explained", j["verdict"]["kind"].get<std::string>().c_str());
  STRCMP_CONTAINS((": " + j["verdict"]["headline"].get<std::string>() + "; ").c_str(), r.out.c_str());
  STRCMP_EQUAL("2024-04-20T00:00:00Z", j["prediction"]["time"].get<std::string>().c_str());
  CHECK_TRUE(j["prediction"]["improved"]["sensors"].contains("LDWN-1"));
  const std::string v = Slurp(vtk);
  CHECK_TRUE(v.find("wear_mm_baseline") != std::string::npos);
  CHECK_TRUE(v.find("wear_mm_improved") != std::string::npos);
  CHECK_TRUE(Slurp(html).find("<svg") != std::string::npos);
  // No temporaries left next to the outputs.
  for (const auto& e : fs::directory_iterator(dir)) CHECK_TRUE(e.path().string().find(".tmp") == std::string::npos);
}

TEST(Linerwatch, ReconstructUsesTheIntervalCentreLikeTheServerAndLowerBoundOnRequest) {
  const fs::path b = Bundle();
  const lw::core::Bundle bundle = lw::core::LoadBundle(b);
  const auto centre = lw::core::Reconstruct(
      bundle.crusher, bundle.map, lw::core::SensorWearAt(bundle.crusher, bundle.readings, lw::core::TimePoint::max(), true));
  const auto lower = lw::core::Reconstruct(
      bundle.crusher, bundle.map, lw::core::SensorWearAt(bundle.crusher, bundle.readings, lw::core::TimePoint::max(), false));
  const Run a = Cli({"reconstruct", b.string(), "--json", (dir / "a.json").string()});
  const Run l = Cli({"reconstruct", b.string(), "--lower-bound", "--json", (dir / "l.json").string()});
  LONGS_EQUAL(0, a.code);
  LONGS_EQUAL(0, l.code);
  DOUBLES_EQUAL(centre.min_thickness_mm, nlohmann::json::parse(Slurp(dir / "a.json"))["min_thickness_mm"].get<double>(), 1e-9);
  DOUBLES_EQUAL(lower.min_thickness_mm, nlohmann::json::parse(Slurp(dir / "l.json"))["min_thickness_mm"].get<double>(), 1e-9);
  // The lower bound means 0.5 mm more wear at every sensor: more wear everywhere (the thinnest
  // point itself may be worn through, 0 mm, in both).
  CHECK(lower.rows[1].min_thickness_mm < centre.rows[1].min_thickness_mm);
  CHECK(lower.min_thickness_mm <= centre.min_thickness_mm);
  CHECK(lower.min_thickness_mm >= 0.0);
}

// A sensor that stopped reporting sets no row scale, as in the server (docs/wear.md, Global wear):
// `reconstruct` names it and its result equals the bundle without that sensor's readings at all.
TEST(Linerwatch, ReconstructLeavesOutASensorThatStoppedReporting) {
  const fs::path b = Bundle();
  lw::core::Bundle bundle = lw::core::LoadBundle(b);
  const std::string dead = bundle.crusher.sensors.at(0).id;
  lw::core::TimePoint first = bundle.readings.front().time, last = first;
  for (const auto& r : bundle.readings) {
    first = std::min(first, r.time);
    last = std::max(last, r.time);
  }
  const lw::core::TimePoint cut = first + (last - first) / 2;
  {
    std::ofstream out(b / "readings.csv");
    out << "time,sensor_id,thickness_mm\n";
    for (const auto& r : bundle.readings)
      if (r.sensor_id != dead || r.time <= cut)
        out << lw::core::FormatIsoTime(r.time) << ',' << r.sensor_id << ',' << r.thickness_mm << '\n';
  }
  CheckReconstructLeavesOut(b, bundle, dead, "stale sensors", "sensors_stale");
}

// A sensor whose value stops moving while the others of its row wear on (stuck) sets no row scale
// either: `reconstruct` names it and equals the bundle without that sensor's readings.
TEST(Linerwatch, ReconstructLeavesOutAStuckSensor) {
  const fs::path b = Bundle();
  lw::core::Bundle bundle = lw::core::LoadBundle(b);
  std::string stuck;  // the last sensor of the fastest-wearing row that has others
  std::map<std::string, int> in_row;
  for (const auto& s : bundle.crusher.sensors) ++in_row[s.row];
  lw::core::TimePoint last = bundle.readings.front().time;
  std::map<std::string, double> first_mm, last_mm;
  for (const auto& r : bundle.readings) {
    last = std::max(last, r.time);
    if (!first_mm.contains(r.sensor_id)) first_mm[r.sensor_id] = r.thickness_mm;
    last_mm[r.sensor_id] = r.thickness_mm;
  }
  double fastest = 0;
  for (const auto& s : bundle.crusher.sensors)
    if (in_row[s.row] >= 3 && first_mm[s.id] - last_mm[s.id] >= fastest) {
      fastest = first_mm[s.id] - last_mm[s.id];
      stuck = s.id;
    }
  CHECK(!stuck.empty());
  const lw::core::TimePoint froze = lw::core::AddDays(last, -20);
  double frozen = -1;
  for (const auto& r : bundle.readings)
    if (r.sensor_id == stuck && r.time <= froze) frozen = r.thickness_mm;
  {
    std::ofstream out(b / "readings.csv");
    out << "time,sensor_id,thickness_mm\n";
    for (const auto& r : bundle.readings)
      out << lw::core::FormatIsoTime(r.time) << ',' << r.sensor_id << ','
          << (r.sensor_id == stuck && r.time > froze ? frozen : r.thickness_mm) << '\n';
  }
  CheckReconstructLeavesOut(b, bundle, stuck, "stuck sensors", "sensors_stuck");
  // With the scan (the last day, after it froze): its frozen value sets no scale at the scan either,
  // so the result equals that of the bundle without its readings, scan and all (core::ScanSensorWear).
  const fs::path without = dir / "without";
  fs::copy(b, without, fs::copy_options::recursive);
  {
    std::ofstream out(without / "readings.csv");
    out << "time,sensor_id,thickness_mm\n";
    for (const auto& r : bundle.readings)
      if (r.sensor_id != stuck) out << lw::core::FormatIsoTime(r.time) << ',' << r.sensor_id << ',' << r.thickness_mm << '\n';
  }
  const Run scanned = Cli({"reconstruct", b.string(), "--json", (dir / "s.json").string()});
  LONGS_EQUAL(0, scanned.code);
  CHECK_TEXT(scanned.out.find("faces corrected") != std::string::npos, scanned.out.c_str());
  LONGS_EQUAL(0, Cli({"reconstruct", without.string(), "--json", (dir / "w.json").string()}).code);
  const auto with_scan = nlohmann::json::parse(Slurp(dir / "s.json")), reference = nlohmann::json::parse(Slurp(dir / "w.json"));
  DOUBLES_EQUAL(reference["min_thickness_mm"].get<double>(), with_scan["min_thickness_mm"].get<double>(), 1e-9);
  LONGS_EQUAL(reference["rows"].size(), with_scan["rows"].size());
  for (size_t k = 0; k < reference["rows"].size(); ++k)
    DOUBLES_EQUAL(reference["rows"][k]["mean_wear_mm"].get<double>(), with_scan["rows"][k]["mean_wear_mm"].get<double>(), 1e-9);
}

// A bundle that also holds a previous liner's readings (a reline that kept the sensors' ids: dated
// before installed_at, worn): `reconstruct` gives what the liner's own readings give; with nothing
// but those, a one-line error says why there is no number.
TEST(Linerwatch, ReconstructLeavesOutAPreviousLinersReadings) {
  const fs::path b = Bundle();
  const lw::core::Bundle bundle = lw::core::LoadBundle(b);
  const Run own = Cli({"reconstruct", b.string(), "--json", (dir / "own.json").string()});
  LONGS_EQUAL(0, own.code);
  auto write = [&](bool with_own) {
    std::ofstream out(b / "readings.csv");
    out << "time,sensor_id,thickness_mm\n";
    for (const auto& r : bundle.readings) {  // the old liner: 200 days earlier, 40 mm thinner (and denser)
      for (int k = 0; k < 3; ++k)
        out << lw::core::FormatIsoTime(lw::core::AddDays(r.time, -200 - 0.01 * k)) << ',' << r.sensor_id << ','
            << std::max(0.0, r.thickness_mm - 40) << '\n';
      if (with_own) out << lw::core::FormatIsoTime(r.time) << ',' << r.sensor_id << ',' << r.thickness_mm << '\n';
    }
  };
  write(true);
  const Run both = Cli({"reconstruct", b.string(), "--json", (dir / "both.json").string()});
  LONGS_EQUAL(0, both.code);
  const auto a = nlohmann::json::parse(Slurp(dir / "own.json")), c = nlohmann::json::parse(Slurp(dir / "both.json"));
  CHECK_TEXT(a == c, (a.dump().substr(0, 200) + "\n" + c.dump().substr(0, 200)).c_str());
  write(false);
  const Run none = Cli({"reconstruct", b.string()});
  CHECK(none.code != 0);
  CHECK_TEXT(OneLine(none.err) && none.err.find("previous liner") != std::string::npos, none.err.c_str());
}

// `plan BUNDLE --sensors K`: K positions, each inside its row; with as many sensors as crusher.json
// has, the proposed layout's expected band is never wider than today's (today's layout is one of
// the layouts the search starts from); the printout says the same figures.
TEST(Linerwatch, PlanProposesKSensorsInsideTheirRowsNoWiderThanTodaysLayout) {
  const fs::path b = Bundle();
  const lw::core::CrusherConfig crusher = lw::core::LoadCrusherConfig(b / "crusher.json");
  const size_t k = crusher.sensors.size();
  const fs::path out = dir / "plan.json";
  const Run r = Cli({"plan", b.string(), "--sensors", std::to_string(k), "--json", out.string()});
  LONGS_EQUAL_TEXT(0, r.code, r.err.c_str());
  const auto j = nlohmann::json::parse(Slurp(out));
  LONGS_EQUAL(k, j.at("sensors").size());
  for (const auto& s : j["sensors"]) {
    const int row = crusher.RowIndex(s.at("row").get<std::string>());
    CHECK_TEXT(row >= 0, s.dump().c_str());
    const lw::core::Row& rr = crusher.rows[static_cast<size_t>(row)];
    const double z = s.at("z_m").get<double>(), theta = s.at("theta_deg").get<double>();
    CHECK_TEXT(z > rr.z_min_m && z < rr.z_max_m, s.dump().c_str());
    CHECK_TEXT(theta >= 0 && theta < 360, s.dump().c_str());
  }
  const double current = j.at("expected_band_mm").at("current").get<double>();
  const double proposed = j.at("expected_band_mm").at("proposed").get<double>();
  CHECK_TEXT(proposed > 0 && proposed <= current + 1e-9, j["expected_band_mm"].dump().c_str());
  char figure[32];
  std::snprintf(figure, sizeof figure, "%.1f mm", proposed);
  CHECK_TEXT(r.out.find(figure) != std::string::npos, r.out.c_str());
}

// Where K gives every row two sensors the plan leaves none with one: one sensor's row scale carries
// only the map's sampling error there, and a search minimising that band sought such rows out
// (bench/diagnosis/RESULTS.md, *Why the plan's bands miss in 5 of 60 cases*). On a real LIGGGHTS
// map where the search alone put one sensor in BOTTOM and five in UPPER.
TEST(Linerwatch, PlanLeavesEveryRowTwoSensorsWhenKGivesThem) {
  const fs::path folder = fs::path(LW_DATA_DIR) / "dem-heldout8" / "c5060-coarse";
  const lw::core::CrusherConfig crusher = lw::core::LoadCrusherConfig(folder / "crusher.json");
  const size_t k = 2 * crusher.rows.size() + 2;
  const fs::path out = dir / "plan.json";
  const Run r = Cli({"plan", folder.string(), "--sensors", std::to_string(k), "--json", out.string()});
  LONGS_EQUAL_TEXT(0, r.code, r.err.c_str());
  const auto j = nlohmann::json::parse(Slurp(out));
  LONGS_EQUAL(k, j.at("sensors").size());
  for (const lw::core::Row& row : crusher.rows) {
    size_t n = 0;
    for (const auto& s : j["sensors"]) n += s.at("row").get<std::string>() == row.name;
    CHECK_TEXT(n >= 2, (row.name + ": " + j["sensors"].dump()).c_str());
  }
}

// Where K leaves some row one sensor, that row is one of the slowest, never the one where the
// thinnest area is expected: a one-sensor row has no scale spread of its own, its band looks
// narrower than it is, and the search took a sensor from the fastest-wearing row for it (a miss
// 5.6 bands out on a held-out chamber). The fastest-wearing row: the most predicted mean wear at
// the reline point if every crusher.json sensor read what the map predicts, as the plan judges
// layouts.
TEST(Linerwatch, PlanKeepsTwoSensorsWhereTheThinnestAreaIsExpected) {
  const fs::path folder = fs::path(LW_DATA_DIR) / "dem-heldout8" / "c6580-steep4";
  const lw::core::CrusherConfig crusher = lw::core::LoadCrusherConfig(folder / "crusher.json");
  const lw::core::WearMap map = lw::core::LoadWearMap(folder / "wear_map.vtk");
  const lw::core::ReconstructionPlan plan = lw::core::PrepareReconstruction(crusher, map);
  const double scale = (crusher.thickness_new_mm - crusher.thickness_min_mm) / plan.intensity.maxCoeff();
  std::vector<lw::core::SensorWear> wear;
  std::vector<lw::core::Reading> used;
  for (size_t s = 0; s < crusher.sensors.size(); ++s) {
    const double w = scale * plan.sensor_intensity[static_cast<Eigen::Index>(s)];
    wear.push_back({crusher.sensors[s].id, w});
    used.push_back({crusher.installed_at, crusher.sensors[s].id, crusher.thickness_new_mm - w, 0});
  }
  std::vector<std::pair<double, std::string>> by_thickness;  // by the rows' mean wear, fastest first
  for (const lw::core::RowSummary& row : lw::core::Reconstruct(plan, wear).rows)
    by_thickness.emplace_back(-row.mean_wear_mm, row.row);
  std::sort(by_thickness.begin(), by_thickness.end());
  const size_t k = 2 * crusher.rows.size() - 1;
  const fs::path out = dir / "plan.json";
  const Run r = Cli({"plan", folder.string(), "--sensors", std::to_string(k), "--json", out.string()});
  LONGS_EQUAL_TEXT(0, r.code, r.err.c_str());
  const auto j = nlohmann::json::parse(Slurp(out));
  std::map<std::string, size_t> n;
  for (const auto& s : j["sensors"]) ++n[s.at("row").get<std::string>()];
  for (size_t i = 0; i + 1 < by_thickness.size(); ++i)  // every row but the slowest keeps two
    CHECK_TEXT(n[by_thickness[i].second] >= 2, (by_thickness[i].second + ": " + j["sensors"].dump()).c_str());
  CHECK_TEXT(n[by_thickness.back().second] >= 1, j["sensors"].dump().c_str());
}

// The rows are ranked for their second sensor by their predicted wear (rate), one measure for every
// row, not by their thinnest areas, which differ in shape and size from row to row (a supported
// small square in one, the whole row in another). LDWN wears 0.5 units a day but 2.5 in a 0.2 m
// band at its discharge edge, LUP 1.2 all over: by the thinnest areas (here each row's 0.1 m square)
// LDWN is first, by predicted wear LUP, which keeps two of K = 3.
TEST(Linerwatch, PlanRanksRowsForTheirSecondSensorByTheirPredictedWear) {
  const fs::path folder = dir / "rank";
  fs::create_directories(folder);
  {
    nlohmann::json config = nlohmann::json::parse(lw::test::kCrusherJson);
    config["thinnest_area"] = {{"band_half_width_mm", 120}};  // every row's area: its thinnest 0.1 m square
    std::ofstream(folder / "crusher.json") << config.dump();
  }
  lw::core::WearMap m = lw::test::CylinderMap(72, 40, [](double z) { return z < 0.2 ? 2.5 : z < 1.0 ? 0.5 : 1.2; });
  lw::core::WriteWearMapVtk(folder / "wear_map.vtk", m, {{"wear", &m.wear}});
  // The two rankings differ here, as the plan judges layouts: crusher.json's sensors reading what
  // the map predicts at the reline point.
  const lw::core::CrusherConfig crusher = lw::core::LoadCrusherConfig(folder / "crusher.json");
  const lw::core::WearMap map = lw::core::LoadWearMap(folder / "wear_map.vtk");
  lw::core::ReconstructionOptions o;
  o.calibration_prior_dof = 0;
  const lw::core::ReconstructionPlan plan = lw::core::PrepareReconstruction(crusher, map, o);
  const double scale = (crusher.thickness_new_mm - crusher.thickness_min_mm) / plan.intensity.maxCoeff();
  std::vector<lw::core::SensorWear> wear;
  std::vector<lw::core::Reading> used;
  for (size_t s = 0; s < crusher.sensors.size(); ++s) {
    const double w = scale * plan.sensor_intensity[static_cast<Eigen::Index>(s)];
    wear.push_back({crusher.sensors[s].id, w});
    used.push_back({crusher.installed_at, crusher.sensors[s].id, crusher.thickness_new_mm - w, 0});
  }
  const lw::core::Reconstruction rec = lw::core::Reconstruct(plan, wear);
  const lw::core::ThinnestAreas areas = lw::core::FindThinnestAreas(plan, rec, used);
  CHECK(rec.rows[1].mean_wear_mm > rec.rows[0].mean_wear_mm);
  CHECK_TEXT(areas.rows[0].thickness_mm < areas.rows[1].thickness_mm,
             (lw::core::ThinnestAreaText(areas.rows[0]) + " / " + lw::core::ThinnestAreaText(areas.rows[1])).c_str());
  const fs::path out = dir / "plan.json";
  const Run r = Cli({"plan", folder.string(), "--sensors", "3", "--json", out.string()});
  LONGS_EQUAL_TEXT(0, r.code, r.err.c_str());
  const auto j = nlohmann::json::parse(Slurp(out));
  std::map<std::string, size_t> n;
  for (const auto& s : j["sensors"]) ++n[s.at("row").get<std::string>()];
  CHECK_TEXT(n["LUP"] == 2 && n["LDWN"] == 1, j["sensors"].dump().c_str());
}

// Bad input: a one-line reason, a non-zero status and no --json file.
TEST(Linerwatch, PlanRefusesBadInputWithOneLineAndNoOutput) {
  const fs::path b = Bundle();
  const fs::path out = dir / "plan.json";
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"plan", b.string(), "--sensors", "0", "--json", out.string()},
        std::vector<std::string>{"plan", b.string(), "--sensors", "99999", "--json", out.string()},
        std::vector<std::string>{"plan", (dir / "nothing-here").string(), "--sensors", "4", "--json", out.string()},
        std::vector<std::string>{"plan", b.string(), "--json", out.string()}}) {
    const Run r = Cli(args);
    CHECK_TEXT(r.code != 0, args[2].c_str());
    CHECK_TEXT(!r.err.empty() && std::count(r.err.begin(), r.err.end(), '\n') == 1, r.err.c_str());
    CHECK_TEXT(!fs::exists(out), args[2].c_str());
  }
  // A crusher.json joint list that is not angles is refused naming the key.
  auto cj = nlohmann::json::parse(Slurp(b / "crusher.json"));
  cj["concave"]["joints_theta_deg"] = nlohmann::json::array({10.0, "north"});
  std::ofstream(b / "crusher.json") << cj.dump(2);
  const Run r = Cli({"plan", b.string(), "--sensors", "4", "--json", out.string()});
  CHECK(r.code != 0);
  CHECK_TEXT(r.err.find("joints_theta_deg") != std::string::npos, r.err.c_str());
  CHECK(!fs::exists(out));
}
