// Estimate(model, window, at) is live wear for every caller: the server's REST wear equals
// `linerwatch reconstruct --json` on the same bundle, GET .../wear?at=TIME equals `linerwatch
// reconstruct --at TIME` (the readings and scans up to TIME only), and a bad `at` is refused naming it.
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "core/csv.hpp"
#include "core/time.hpp"
#include "server/rest.hpp"
#include "support/temp_directory.hpp"
#include "unit/cli/run_cli.hpp"
#include "unit/server/server_fixture.hpp"

#include <CppUTest/TestHarness.h>  // last: its leak-detection macros clash with std headers

using namespace lw::server;
using nlohmann::json;

namespace {

constexpr double kScanDay = 12;

/// A 20-day campaign with its laser scan on day 12: a time before the scan and one after it.
lw::test::CrusherFolder& Folder() {
  static lw::test::CrusherFolder f(20, 5, kScanDay);
  return f;
}

lw::core::TimePoint Day(double d) {
  return lw::core::AddDays(Folder().bundle.crusher.installed_at, d);
}

/// A server's parts over the folder, every reading of the bundle posted.
struct Served {
  lw::test::ServerParts parts{Folder().crushers, false};
  std::unique_ptr<rest::Resources> resources = std::make_unique<rest::Resources>(parts.ctx);
  Served() {
    json body = {{"readings", json::array()}};
    for (const auto& m : lw::test::Messages(Folder().bundle)) body["readings"].push_back(json::parse(m.payload));
    const std::string text = body.dump();
    rest::Request post;
    post.path = {Folder().id()};
    post.body = text;
    const rest::Response r =
        resources->Call(rest::Resources::Find(rest::Method::kPost, "/api/v1/crushers/{crusher}/readings"), post);
    LONGS_EQUAL_TEXT(200, r.status, r.json.dump().substr(0, 300).c_str());
  }
  rest::Response Wear(QueryParams query = {}) {
    rest::Request get;
    get.path = {Folder().id()};
    get.query = std::move(query);
    return lw::test::WithJson(resources->Call(rest::Resources::Find(rest::Method::kGet, "/api/v1/crushers/{crusher}/wear"), get));
  }
  rest::Response Forecast(QueryParams query = {}) {
    rest::Request get;
    get.path = {Folder().id()};
    get.query = std::move(query);
    return lw::test::WithJson(
        resources->Call(rest::Resources::Find(rest::Method::kGet, "/api/v1/crushers/{crusher}/forecast"), get));
  }
};

Served& Server() {
  static Served s;
  return s;
}

/// `linerwatch reconstruct` on the folder (a bundle) with `extra` options: its --json.
json Reconstruct(const std::vector<std::string>& extra) {
  lw::test::TempDirectory tmp{"lw-estimate"};
  const std::string out = tmp.File("r.json");
  std::vector<std::string> args = {"reconstruct", Folder().folder, "--json", out};
  args.insert(args.end(), extra.begin(), extra.end());
  const lw::test::CliRun r = lw::test::RunLinerwatch(args);
  LONGS_EQUAL_TEXT(0, r.code, r.err.c_str());
  std::ifstream in(out);
  return json::parse(in);
}

/// The served wear (`served`, REST JSON) is the reconstruction `cli` (reconstruct --json) reports.
void CheckSameWear(const json& served, const json& cli) {
  CHECK_TEXT(served["thinnest_area"] == cli["thinnest_area"],
             (served["thinnest_area"].dump() + "\n" + cli["thinnest_area"].dump()).c_str());
  CHECK(served["status"] == cli["status"]);
  CHECK(served["map_error_at_sensors"] == cli["map_error_at_sensors"]);
  CHECK(served["sensors_stale"] == cli["sensors_stale"]);
  CHECK(served["sensors_stuck"] == cli["sensors_stuck"]);
  CHECK(served["face_level"] == cli["face_level"]);
  DOUBLES_EQUAL(cli["min_thickness_mm"].get<double>(), served["min_thickness_mm"].get<double>(), 0.0005 + 1e-9);
  LONGS_EQUAL(cli["rows"].size(), served["rows"].size());
  for (size_t k = 0; k < cli["rows"].size(); ++k) {
    const json &s = served["rows"][k], &c = cli["rows"][k];
    CHECK(s["row"] == c["row"]);
    CHECK(s["thinnest_area"] == c["thinnest_area"]);
    CHECK(s["sensors_used"] == c["sensors_used"]);
    DOUBLES_EQUAL(c["min_thickness_mm"].get<double>(), s["min_thickness_mm"].get<double>(), 0.0005 + 1e-9);
  }
}

/// The smallest remaining_mm of a per-face wear CSV (GET .../wear?format=csv).
double CsvMinRemaining(const std::string& csv) {
  std::istringstream in(csv);
  std::string line;
  std::getline(in, line);
  CHECK_EQUAL(std::string("face,row,z_m,theta_deg,remaining_mm,remaining_sd_mm,wear_mm"), line.substr(0, line.find('\r')));
  double lowest = std::numeric_limits<double>::infinity();
  while (std::getline(in, line)) {
    std::vector<std::string> fields;
    std::stringstream ss(line);
    for (std::string f; std::getline(ss, f, ',');) fields.push_back(f);
    CHECK_TEXT(fields.size() >= 5, line.c_str());
    lowest = std::min(lowest, std::stod(fields[4]));
  }
  return lowest;
}

/// The smallest value of a legacy-VTK cell array `name` (GET .../wear?format=vtk).
double VtkMinOf(const std::string& vtk, const std::string& name) {
  const std::string head = "SCALARS " + name + " double 1\nLOOKUP_TABLE default\n";
  const size_t at = vtk.find(head);
  CHECK_TEXT(at != std::string::npos, name.c_str());
  std::istringstream in(vtk.substr(at + head.size()));
  double lowest = std::numeric_limits<double>::infinity();
  for (std::string line; std::getline(in, line) && !line.empty() && line.rfind("SCALARS", 0) != 0;)
    lowest = std::min(lowest, std::stod(line));
  return lowest;
}

}  // namespace

TEST_GROUP(EstimateCallers){};

TEST(EstimateCallers, RestWearEqualsReconstructJsonOnTheSameBundle) {
  const rest::Response res = Server().Wear({{"faces", "false"}});
  LONGS_EQUAL(200, res.status);
  CHECK_FALSE(res.json.contains("at"));
  CHECK(res.json["scan"].is_object());  // the folder's scan applies to both
  CheckSameWear(res.json, Reconstruct({}));
}

// ?at=TIME: the readings up to TIME and the scans up to TIME, as `linerwatch reconstruct --at TIME`;
// before the scan's date no scan applies, and the wear is less than now.
TEST(EstimateCallers, AtGivesTheReconstructOfTheReadingsUpToThatTime) {
  const double now_min = Server().Wear({{"faces", "false"}}).json["min_thickness_mm"].get<double>();
  for (const double day : {kScanDay - 4, kScanDay + 3}) {
    const std::string at = lw::core::FormatIsoTime(Day(day));
    const rest::Response res = Server().Wear({{"at", at}, {"faces", "false"}});
    LONGS_EQUAL_TEXT(200, res.status, res.json.dump().substr(0, 300).c_str());
    CHECK_EQUAL(at, res.json["at"].get<std::string>());
    const auto time = lw::core::ParseIsoTime(res.json["time"].get<std::string>());
    CHECK(time && *time <= Day(day) && *time > Day(day - 1));
    for (const auto& r : res.json["readings_used"]) CHECK(*lw::core::ParseIsoTime(r["time"].get<std::string>()) <= Day(day));
    CHECK_EQUAL(day > kScanDay, res.json["scan"].is_object());
    CheckSameWear(res.json, Reconstruct({"--at", at}));
    // Thicker then than now: the past time's readings, not the latest.
    CHECK_TEXT(res.json["min_thickness_mm"].get<double>() > now_min + 0.5, res.json["min_thickness_mm"].dump().c_str());
    // The per-face CSV at the same time.
    const rest::Response csv = Server().Wear({{"at", at}, {"format", "csv"}});
    LONGS_EQUAL(200, csv.status);
    CHECK(csv.raw.has_value());
    DOUBLES_EQUAL(res.json["min_thickness_mm"].get<double>(), CsvMinRemaining(csv.raw->content), 0.0011);
  }
}

// The VTK for ParaView at a past time carries that time's wear, not the latest.
TEST(EstimateCallers, AtGivesThatTimesWearAsVtkToo) {
  const std::string at = lw::core::FormatIsoTime(Day(kScanDay - 4));
  const rest::Response past = Server().Wear({{"at", at}, {"format", "vtk"}});
  const rest::Response now = Server().Wear({{"format", "vtk"}});
  LONGS_EQUAL(200, past.status);
  CHECK(past.raw.has_value() && now.raw.has_value());
  const double past_min = Server().Wear({{"at", at}, {"faces", "false"}}).json["min_thickness_mm"].get<double>();
  DOUBLES_EQUAL(past_min, VtkMinOf(past.raw->content, "remaining_mm"), 0.0011);
  CHECK(VtkMinOf(past.raw->content, "remaining_mm") > VtkMinOf(now.raw->content, "remaining_mm") + 0.5);
}

// GET .../forecast?at=TIME: the reline dates as they were forecast from the readings up to TIME.
TEST(EstimateCallers, AtGivesTheForecastMadeFromTheReadingsUpToThatTime) {
  const rest::Response now = Server().Forecast();
  LONGS_EQUAL(200, now.status);
  CHECK_FALSE(now.json.contains("at"));
  const std::string at = lw::core::FormatIsoTime(Day(kScanDay - 4));
  const rest::Response past = Server().Forecast({{"at", at}});
  LONGS_EQUAL_TEXT(200, past.status, past.json.dump().substr(0, 300).c_str());
  CHECK_EQUAL(at, past.json["at"].get<std::string>());
  for (const auto& r : past.json["readings_used"])
    CHECK(*lw::core::ParseIsoTime(r["time"].get<std::string>()) <= Day(kScanDay - 4));
  LONGS_EQUAL(now.json["rows"].size(), past.json["rows"].size());
  for (size_t k = 0; k < now.json["rows"].size(); ++k) {
    const json &p = past.json["rows"][k], &n = now.json["rows"][k];
    if (!n["min_thickness_mm"].is_number()) continue;
    CHECK_TEXT(p["min_thickness_mm"].get<double>() > n["min_thickness_mm"].get<double>() + 0.5, p.dump().c_str());
  }
  // The CSV form at the same time, and a bad time refused naming `at`.
  const rest::Response csv = Server().Forecast({{"at", at}, {"format", "csv"}});
  LONGS_EQUAL(200, csv.status);
  CHECK(csv.raw.has_value());
  const rest::Response bad = Server().Forecast({{"at", "2024-02-30"}});
  LONGS_EQUAL(400, bad.status);
  CHECK(bad.json.at("error").get<std::string>().find("at") != std::string::npos);
}

TEST(EstimateCallers, BadAtIsRefusedNamingIt) {
  const std::string before = lw::core::FormatIsoTime(Day(-2));
  // After the server's "now" (the ingestor's clock, the one readings are validated against).
  const std::string future =
      lw::core::FormatIsoTime(lw::core::TimePoint(std::chrono::seconds(Server().parts.ingestor->NowS() + 1)));
  for (const std::string& at : {std::string("yesterday"), std::string("2024-02-30"), before, future}) {
    for (const char* format : {"json", "csv"}) {
      const rest::Response res = Server().Wear({{"at", at}, {"format", format}});
      LONGS_EQUAL_TEXT(400, res.status, (at + " " + format).c_str());
      CHECK_FALSE(res.raw.has_value());
      const std::string error = res.json.at("error").get<std::string>();
      CHECK_TEXT(error.find("at") != std::string::npos && error.find(at) != std::string::npos, error.c_str());
    }
  }
}

// GET .../plan?sensors=K is `linerwatch plan CRUSHER_DIR --sensors K --json` on the same folder and
// readings: the same layout, bands and scan advice; a missing or out-of-range K is refused by name.
TEST(EstimateCallers, RestPlanEqualsThePlanCommand) {
  const auto plan = [](QueryParams query) {
    rest::Request get;
    get.path = {Folder().id()};
    get.query = std::move(query);
    return Server().resources->Call(rest::Resources::Find(rest::Method::kGet, "/api/v1/crushers/{crusher}/plan"), get);
  };
  const rest::Response res = plan({{"sensors", "5"}});
  LONGS_EQUAL_TEXT(200, res.status, res.json.dump().substr(0, 300).c_str());
  lw::test::TempDirectory tmp{"lw-estimate-plan"};
  const std::string out = tmp.File("plan.json");
  const lw::test::CliRun r = lw::test::RunLinerwatch({"plan", Folder().folder, "--sensors", "5", "--json", out});
  LONGS_EQUAL_TEXT(0, r.code, r.err.c_str());
  std::ifstream in(out);
  const json cli = json::parse(in);
  LONGS_EQUAL(5, res.json["sensors"].size());
  for (const char* key : {"sensors", "expected_band_mm", "liner_band_mm", "rows", "candidates", "scan_now"})
    CHECK_TEXT(json::parse(res.json[key].dump()) == cli[key],
               (std::string(key) + ": " + res.json[key].dump() + "\n" + cli[key].dump()).c_str());
  CHECK(res.json["scan_now"].is_object());  // a running campaign: what a scan now would do
  for (const QueryParams& bad : {QueryParams{}, QueryParams{{"sensors", "0"}}, QueryParams{{"sensors", "many"}}}) {
    const rest::Response refused = plan(bad);
    LONGS_EQUAL(400, refused.status);
    CHECK(refused.json["error"].get<std::string>().find("sensors") != std::string::npos);
  }
}
