#include "core/bundle.hpp"
#include <nlohmann/json.hpp>
#include "unit/core/bundle_fixture.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw::core;
namespace fs = std::filesystem;

namespace {
std::string ErrorOf(const lw::test::TempDirectory& dir) {
  try {
    LoadBundle(dir.path());
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST_GROUP(Bundle) {
  lw::test::TempDirectory dir;
};

TEST(Bundle, LoadsEveryFileSortedAndIgnoresExtras) {
  lw::test::WriteBundle(dir,
                        "time,sensor_id,thickness_mm,comment\n"
                        "2026-01-03T00:00:00Z,1002,118,x\n2026-01-02T00:00:00Z,1001,119,\n"
                        "2026-01-01T00:00:00Z,1002,120,\n2026-01-02T00:00:00Z,1001,119,dup\n");
  dir.Write("operations.csv", "time,throughput_tph,ore_ai,mill\n2026-01-02T00:00:00Z,3400,0.3,a\n2026-01-01T00:00:00Z,3500,,b\n");
  dir.Write("scans/scan_2026-02-01.xyz", "1.01 0 0.5\n# comment\n0 1.02 1.5\n");
  dir.Write("notes.txt", "ignored");
  const Bundle b = LoadBundle(dir.path());
  STRCMP_EQUAL("cr1", b.crusher.crusher_id.c_str());
  LONGS_EQUAL(2, b.crusher.rows.size());
  CHECK(b.crusher.sensors[1].address == 0x0013A20040A1B2C3ull);
  DOUBLES_EQUAL(120.0, b.crusher.sensors[0].thickness_new_mm, 1e-12);
  LONGS_EQUAL(4, b.readings.size());  // duplicates kept
  STRCMP_EQUAL("1001", b.readings[0].sensor_id.c_str());
  STRCMP_EQUAL("1002", b.readings[2].sensor_id.c_str());
  CHECK(b.readings[2].time < b.readings[3].time);
  LONGS_EQUAL(2, b.operations.size());
  DOUBLES_EQUAL(3500, b.operations[0].throughput_tph, 1e-12);
  CHECK_FALSE(b.operations[0].ore_ai.has_value());
  DOUBLES_EQUAL(0.3, *b.operations[1].ore_ai, 1e-12);
  LONGS_EQUAL(1, b.scans.size());
  LONGS_EQUAL(2, b.scans[0].points.size());
  STRCMP_EQUAL("2026-02-01T00:00:00Z", FormatIsoTime(b.scans[0].date).c_str());
  LONGS_EQUAL(960, b.map.face_count());
}

TEST(Bundle, BadReadingsNameFileLineAndRule) {
  lw::test::WriteBundle(dir, "time,sensor_id,thickness_mm\n2026-01-02T00:00:00Z,1001,119\n2026-01-02T00:00:00Z,1001,abc\n");
  std::string e = ErrorOf(dir);
  CHECK(e.find("readings.csv:3") != std::string::npos);
  CHECK(e.find("thickness_mm 'abc' is not a number") != std::string::npos);
  lw::test::WriteBundle(dir, "time,sensor_id,thickness_mm\n2026-01-02T00:00:00Z,9999,119\n");
  e = ErrorOf(dir);
  CHECK(e.find("readings.csv:2") != std::string::npos);
  CHECK(e.find("'9999'") != std::string::npos);
  lw::test::WriteBundle(dir, "time,sensor_id,thickness_mm\nlast tuesday,1001,119\n");
  CHECK(ErrorOf(dir).find("readings.csv:2: time 'last tuesday'") != std::string::npos);
  lw::test::WriteBundle(dir, "time,sensor_id\n");
  CHECK(ErrorOf(dir).find("lacks column 'thickness_mm'") != std::string::npos);
  lw::test::WriteBundle(dir, "time,sensor_id,thickness_mm\n2026-01-02T00:00:00Z,1001,-4\n");
  CHECK(ErrorOf(dir).find("negative") != std::string::npos);
  lw::test::WriteBundle(dir, "time,sensor_id,thickness_mm\n1850-01-02T00:00:00Z,1001,4\n");
  CHECK(ErrorOf(dir).find("outside") != std::string::npos);
}

// history/NAME/ holds the same crusher's earlier campaigns: loaded oldest first, each checked as the
// bundle's own files are, errors naming history/NAME/FILE.
TEST(Bundle, HistoryFoldersAreEarlierCampaignsOfTheSameCrusher) {
  lw::test::WriteBundle(dir, "time,sensor_id,thickness_mm\n2026-01-02T00:00:00Z,1001,119\n");
  auto old_json = [](const std::string& from, const std::string& to) {
    std::string j = lw::test::kCrusherJson;
    j.replace(j.find(from), from.size(), to);
    return j;
  };
  const std::string installed = "\"installed_at\": \"2026-01-01T00:00:00Z\"";
  dir.Write("history/b-2025/crusher.json", old_json(installed, "\"installed_at\": \"2025-06-01T00:00:00Z\""));
  dir.Write("history/b-2025/readings.csv", "time,sensor_id,thickness_mm\n2025-07-01T00:00:00Z,1001,100\n");
  dir.Write("history/b-2025/scans/scan_2025-12-30.xyz", "1 0 0.5\n");
  dir.Write("history/a-2025/crusher.json", old_json(installed, "\"installed_at\": \"2025-01-01T00:00:00Z\""));
  Bundle b = LoadBundle(dir.path());
  LONGS_EQUAL(2, b.history.size());
  STRCMP_EQUAL("a-2025", b.history[0].name.c_str());  // oldest first, by installed_at
  STRCMP_EQUAL("b-2025", b.history[1].name.c_str());
  LONGS_EQUAL(1, b.history[1].readings.size());
  LONGS_EQUAL(1, b.history[1].scans.size());
  LONGS_EQUAL(0, b.history[0].scans.size());

  dir.Write("history/b-2025/readings.csv", "time,sensor_id,thickness_mm\n2025-07-01T00:00:00Z,1001,500\n");
  std::string e = ErrorOf(dir);
  CHECK_TEXT(e.find("history/b-2025/readings.csv:2: thickness_mm 500 is outside") != std::string::npos, e.c_str());
  dir.Write("history/b-2025/readings.csv", "time,sensor_id\n");
  CHECK(ErrorOf(dir).find("history/b-2025/readings.csv") != std::string::npos);
  fs::remove(dir.path() / "history/b-2025/readings.csv");
  dir.Write("history/a-2025/crusher.json", old_json("\"crusher_id\": \"cr1\"", "\"crusher_id\": \"cr9\""));
  e = ErrorOf(dir);
  CHECK_TEXT(e.find("history/a-2025/crusher.json: crusher_id 'cr9' is not the bundle's 'cr1'") != std::string::npos, e.c_str());
  dir.Write("history/a-2025/crusher.json", lw::test::kCrusherJson);  // installed with the bundle's liner
  e = ErrorOf(dir);
  CHECK_TEXT(e.find("history/a-2025/crusher.json: installed_at 2026-01-01T00:00:00Z is not before") != std::string::npos,
             e.c_str());
  fs::remove(dir.path() / "history/a-2025/crusher.json");
  STRCMP_EQUAL("", ErrorOf(dir).c_str());  // a folder with none of a campaign's files is ignored
  dir.Write("history/a-2025/readings.csv", "time,sensor_id,thickness_mm\n");
  e = ErrorOf(dir);
  CHECK_TEXT(e.find("history/a-2025/crusher.json: required") != std::string::npos, e.c_str());
}

// The offline tools hold readings to the server's rule (ingest refuses the same values): no value
// above what the sensor's ladder can read, nothing beyond decimal notation.
TEST(Bundle, ReadingsTheServerRefusesAreRefusedByLineAndRule) {
  const std::string head = "time,sensor_id,thickness_mm\n2026-01-02T00:00:00Z,1001,119\n";
  for (const char* value : {"500", "1e308", "121.5"}) {
    lw::test::WriteBundle(dir, head + "2026-01-03T00:00:00Z,1001," + value + "\n");
    const std::string e = ErrorOf(dir);
    CHECK_TEXT(e.find("readings.csv:3: thickness_mm") != std::string::npos, e.c_str());
    CHECK_TEXT(e.find("is outside [0, 121] (sensor '1001'") != std::string::npos, e.c_str());
  }
  for (const char* value : {"0x10", "inf", "nan", "1e999"}) {
    lw::test::WriteBundle(dir, head + "2026-01-03T00:00:00Z,1001," + value + "\n");
    const std::string e = ErrorOf(dir);
    CHECK_TEXT(e.find("readings.csv:3: thickness_mm '" + std::string(value) + "'") != std::string::npos, e.c_str());
  }
  // A previous liner's reading (before installed_at less a day) is not held to this liner's
  // thickness: the old liner may have been thicker.
  lw::test::WriteBundle(dir, "time,sensor_id,thickness_mm\n2025-12-20T00:00:00Z,1001,150\n" + head.substr(head.find('\n') + 1));
  STRCMP_EQUAL("", ErrorOf(dir).c_str());
  // One ladder loop above the as-new thickness is a reading, as the server takes it.
  lw::test::WriteBundle(dir, head + "2026-01-03T00:00:00Z,1001,121\n");
  STRCMP_EQUAL("", ErrorOf(dir).c_str());
}

TEST(Bundle, BadCrusherJsonIsRefusedWithTheRule) {
  lw::test::WriteBundle(dir, "time,sensor_id,thickness_mm\n");
  std::string j = lw::test::kCrusherJson;
  dir.Write("crusher.json", j.replace(j.find("\"row\": \"LUP\""), 12, "\"row\": \"LX\""));
  CHECK(ErrorOf(dir).find("sensor '1002' names row 'LX' that is not in concave.rows") != std::string::npos);
  dir.Write("crusher.json", "{\"crusher_id\": \"cr1\",\n \"installed_at\": }");
  const std::string e = ErrorOf(dir);
  CHECK(e.find("crusher.json:2") != std::string::npos);
  CHECK(e.find("not valid JSON") != std::string::npos);
  std::filesystem::remove(dir.path() / "wear_map.vtk");
  dir.Write("crusher.json", lw::test::kCrusherJson);
  CHECK(ErrorOf(dir).find("wear_map.vtk") != std::string::npos);
}

// Found by fuzz/ (fuzz_bundle): nlohmann::json throws out_of_range, not parse_error, for a number
// beyond double range, and it escaped LoadBundle instead of an InputError naming the file.
TEST(Bundle, NumberBeyondDoubleRangeInCrusherJsonIsAnInputError) {
  lw::test::WriteBundle(dir, "time,sensor_id,thickness_mm\n");
  std::string j = lw::test::kCrusherJson;
  const size_t at = j.find("\"crusher_id\"");
  dir.Write("crusher.json", j.insert(at, "\"scale\": 1e999, "));
  const std::string e = ErrorOf(dir);
  CHECK_TEXT(e.find("crusher.json") != std::string::npos && e.find("does not fit a double") != std::string::npos, e.c_str());
}

TEST(Bundle, BadScansAndOperationsAreRefused) {
  lw::test::WriteBundle(dir, "time,sensor_id,thickness_mm\n");
  dir.Write("scans/scan_2026-02-01.xyz", "1 2\n");
  CHECK(ErrorOf(dir).find("scans/scan_2026-02-01.xyz:1") != std::string::npos);
  std::filesystem::remove_all(dir.path() / "scans");
  dir.Write("scans/scan_feb.xyz", "1 2 3\n");
  CHECK(ErrorOf(dir).find("scan_YYYY-MM-DD.xyz") != std::string::npos);
  std::filesystem::remove_all(dir.path() / "scans");
  dir.Write("operations.csv", "time,throughput_tph\n2026-01-01,lots\n");
  CHECK(ErrorOf(dir).find("operations.csv:2") != std::string::npos);
}

// crusher.json values that would load and then give wrong answers (or can never match a topic,
// or put markup into the dashboard) are refused, naming the rule.
// Finding: a `scans` that is a file, not a folder, was ignored silently (no scan, no word).
TEST(Bundle, ScansThatIsAFileIsRefused) {
  lw::test::WriteBundle(dir, "time,sensor_id,thickness_mm\n");
  STRCMP_EQUAL("", ErrorOf(dir).c_str());
  dir.Write("scans", "0 0 0\n");
  const std::string e = ErrorOf(dir);
  CHECK_TEXT(e.find("is not a folder") != std::string::npos, e.c_str());
}

TEST(Bundle, ImplausibleCrusherJsonIsRefused) {
  lw::test::WriteBundle(dir, "time,sensor_id,thickness_mm\n");
  auto with = [&](const std::string& from, const std::string& to) {
    std::string j = lw::test::kCrusherJson;
    const size_t at = j.find(from);
    CHECK(at != std::string::npos);
    dir.Write("crusher.json", j.replace(at, from.size(), to));
    return ErrorOf(dir);
  };
  for (const char* id : {"\"\"", "\"+\"", "\"10/01\"", "\"<img src=x onerror=alert(1)>\"", "\"a b\""}) {
    const std::string e = with("\"id\": \"1001\"", std::string("\"id\": ") + id);
    CHECK_TEXT(e.find("sensor id") != std::string::npos, e.c_str());
  }
  CHECK(with("\"crusher_id\": \"cr1\"", "\"crusher_id\": \"c<b>\"").find("crusher_id") != std::string::npos);
  // Finding: a key given twice kept its last value silently (a second "site" further down won).
  CHECK(with("\"crusher_id\": \"cr1\"", "\"crusher_id\": \"cr1\", \"site\": \"a\", \"site\": \"b\"")
            .find("key \"site\" appears twice in the top level") != std::string::npos);
  CHECK(with("\"id\": \"1001\"", "\"id\": \"1001\", \"id\": \"1002\"").find("key \"id\" appears twice") != std::string::npos);
  CHECK(with("\"crusher_id\": \"cr1\"", "\"crusher_id\": \"cr1\", \"site\": \"a/b\"").find("site 'a/b'") != std::string::npos);
  CHECK(with("\"z_m\": 0.5", "\"z_m\": 50").find("outside its row 'LDWN'") != std::string::npos);
  CHECK(with("\"theta_deg\": 0", "\"theta_deg\": 9999").find("theta_deg") != std::string::npos);
  CHECK(with("\"z_min_m\": 1.0, \"z_max_m\": 2.0", "\"z_min_m\": 0.5, \"z_max_m\": 2.0").find("overlaps row") !=
        std::string::npos);
  CHECK(with("\"thickness_new_mm\": 120", "\"thickness_new_mm\": 1e999").find("crusher.json") != std::string::npos);
  CHECK(with("\"thickness_new_mm\": 120", "\"thickness_new_mm\": 120000").find("thickness") != std::string::npos);
  // A sensor's own as-new thickness: above the liner's minimum, at most twice the liner's.
  for (const char* t : {"500", "30", "10"}) {
    const std::string e = with("\"id\": \"1001\"", std::string("\"id\": \"1001\", \"thickness_new_mm\": ") + t);
    CHECK_TEXT(e.find("sensor '1001' thickness_new_mm " + std::string(t) + " must be above concave thickness_min_mm (30)") !=
                   std::string::npos,
               e.c_str());
  }
  STRCMP_EQUAL("", with("\"id\": \"1001\"", "\"id\": \"1001\", \"thickness_new_mm\": 140").c_str());
  // Rows and sensors must lie on the map (z in [0, 2] m here): a row at 40-50 m is a units mistake.
  std::string j = lw::test::kCrusherJson;
  j.replace(j.find("\"z_min_m\": 1.0, \"z_max_m\": 2.0"), 30, "\"z_min_m\": 40.0, \"z_max_m\": 50.0");
  j.replace(j.find("\"z_m\": 1.5"), 10, "\"z_m\": 45");
  dir.Write("crusher.json", j);
  CHECK(ErrorOf(dir).find("outside the wear map's z range") != std::string::npos);
  // A site given is kept.
  with("\"crusher_id\": \"cr1\"", "\"crusher_id\": \"cr1\", \"site\": \"plant-2\"");
  STRCMP_EQUAL("plant-2", LoadCrusherConfig(dir.path() / "crusher.json").site.c_str());
}

// crusher.json's "thinnest_area" (the band target and patch ladder of the live headline): kept when
// in range, each value out of range refused naming its key.
TEST(Bundle, ThinnestAreaSettingsAreReadAndOutOfRangeValuesRefusedByName) {
  lw::test::WriteBundle(dir, "time,sensor_id,thickness_mm\n");
  auto with = [&](const std::string& setting) {
    std::string j = lw::test::kCrusherJson;
    j.replace(j.find("\"crusher_id\": \"cr1\""), 19, "\"crusher_id\": \"cr1\", \"thinnest_area\": " + setting);
    dir.Write("crusher.json", j);
    return ErrorOf(dir);
  };
  STRCMP_EQUAL("", with(R"({"band_half_width_mm": 6, "patches_m": [0.15, 0.3], "sensor_reach_m": 0.2})").c_str());
  const CrusherConfig c = LoadCrusherConfig(dir.path() / "crusher.json");
  DOUBLES_EQUAL(6.0, c.thinnest_area.band_half_width_mm, 0);
  CHECK((c.thinnest_area.patches_m == std::vector<double>{0.15, 0.3}));
  DOUBLES_EQUAL(0.2, c.thinnest_area.sensor_reach_m, 0);
  CHECK(with(R"({"band_half_width_mm": 0})").find("thinnest_area.band_half_width_mm") != std::string::npos);
  CHECK(with(R"({"band_half_width_mm": 500})").find("thinnest_area.band_half_width_mm") != std::string::npos);
  CHECK(with(R"({"patches_m": [0.4, 0.2]})").find("thinnest_area.patches_m") != std::string::npos);
  CHECK(with(R"({"patches_m": [0.001]})").find("thinnest_area.patches_m") != std::string::npos);
  CHECK(with(R"({"patches_m": []})").find("thinnest_area.patches_m") != std::string::npos);
  CHECK(with(R"({"sensor_reach_m": -1})").find("thinnest_area.sensor_reach_m") != std::string::npos);
  CHECK(with(R"({"band_half_width_mm": "ten"})").find("band_half_width_mm") != std::string::npos);
  CHECK(with("7").find("thinnest_area") != std::string::npos);
}

// crusher.json's "setting" (the closed-side setting's drift, docs/wear.md): kept when in range,
// every bad key or value refused by name; its alarm rule, setting_open, is off until enabled.
TEST(Bundle, SettingIsReadAndBadKeysRefusedByNameItsAlarmOffByDefault) {
  lw::test::WriteBundle(dir, "time,sensor_id,thickness_mm\n");
  auto with = [&](const std::string& key, const std::string& value) {
    std::string j = lw::test::kCrusherJson;
    j.replace(j.find("\"crusher_id\": \"cr1\""), 19, "\"crusher_id\": \"cr1\", \"" + key + "\": " + value);
    dir.Write("crusher.json", j);
    return ErrorOf(dir);
  };
  const CrusherConfig plain = LoadCrusherConfig(dir.path() / "crusher.json");
  CHECK_FALSE(plain.setting.css_mm.has_value());
  DOUBLES_EQUAL(0.1, plain.setting.ring_height_m, 0);
  CHECK_FALSE(plain.alarms.Rule("setting_open").enabled);
  STRCMP_EQUAL("", with("setting", R"({"css_mm": 125, "ring_height_m": 0.2})").c_str());
  const CrusherConfig c = LoadCrusherConfig(dir.path() / "crusher.json");
  DOUBLES_EQUAL(125, *c.setting.css_mm, 0);
  DOUBLES_EQUAL(0.2, c.setting.ring_height_m, 0);
  STRCMP_CONTAINS("setting.css is not a setting key", with("setting", R"({"css": 125})").c_str());
  STRCMP_CONTAINS("setting.css_mm must be in", with("setting", R"({"css_mm": 0})").c_str());
  STRCMP_CONTAINS("setting.ring_height_m must be in", with("setting", R"({"ring_height_m": 5})").c_str());
  STRCMP_CONTAINS("\"setting\" must be an object", with("setting", "125").c_str());
  STRCMP_EQUAL("", with("alarms", R"({"setting_open": {"enabled": true, "above_mm": 15}})").c_str());
  const CrusherConfig on = LoadCrusherConfig(dir.path() / "crusher.json");
  CHECK(on.alarms.Rule("setting_open").enabled);
  DOUBLES_EQUAL(15, on.alarms.Rule("setting_open").threshold, 0);
  STRCMP_CONTAINS("alarms.setting_open.hysteresis_mm must be at most above_mm",
                  with("alarms", R"({"setting_open": {"above_mm": 1, "hysteresis_mm": 2}})").c_str());
}

// crusher.json's "alarms" (docs/alarms.md): defaults without it (thinnest_area's threshold from the
// liner's minimum), settings given kept and the others left at their defaults, and every bad rule,
// setting, type or value refused naming its key.
TEST(Bundle, AlarmRulesAreReadOverTheDefaultsAndBadValuesRefusedByName) {
  lw::test::WriteBundle(dir, "time,sensor_id,thickness_mm\n");
  auto with = [&](const std::string& setting) {
    std::string j = lw::test::kCrusherJson;
    j.replace(j.find("\"crusher_id\": \"cr1\""), 19, "\"crusher_id\": \"cr1\", \"alarms\": " + setting);
    dir.Write("crusher.json", j);
    return ErrorOf(dir);
  };
  const CrusherConfig plain = LoadCrusherConfig(dir.path() / "crusher.json");
  DOUBLES_EQUAL(plain.thickness_min_mm + 10, plain.alarms.Rule("thinnest_area").threshold, 0);
  DOUBLES_EQUAL(3300, plain.alarms.Rule("battery_low").threshold, 0);
  STRCMP_EQUAL("critical", plain.alarms.Rule("overdue").severity.c_str());
  STRCMP_EQUAL("",
               with(R"({"battery_low": {"below_mv": 3100, "severity": "critical"}, "unsupported": {"enabled": false}})").c_str());
  const CrusherConfig c = LoadCrusherConfig(dir.path() / "crusher.json");
  DOUBLES_EQUAL(3100, c.alarms.Rule("battery_low").threshold, 0);
  DOUBLES_EQUAL(100, c.alarms.Rule("battery_low").hysteresis, 0);
  STRCMP_EQUAL("critical", c.alarms.Rule("battery_low").severity.c_str());
  CHECK_FALSE(c.alarms.Rule("unsupported").enabled);
  CHECK_TRUE(c.alarms.Rule("sensor_silent").enabled);
  // What AlarmConfigJson writes reads back the same.
  const AlarmConfig again = ParseAlarmConfig(nlohmann::json::parse(AlarmConfigJson(c.alarms).dump()), plain.alarms, "x");
  DOUBLES_EQUAL(3100, again.Rule("battery_low").threshold, 0);
  CHECK_FALSE(again.Rule("unsupported").enabled);
  const std::pair<const char*, const char*> bad[] = {
      {R"({"battery": {}})", "alarms.battery is not an alarm rule"},
      {R"({"battery_low": {"below": 3000}})", "alarms.battery_low.below is not a setting"},
      {R"({"battery_low": {"below_mv": -5}})", "alarms.battery_low.below_mv must be in"},
      {R"({"battery_low": {"below_mv": "low"}})", "below_mv"},
      {R"({"reline_due": {"within_days": 5000}})", "alarms.reline_due.within_days"},
      {R"({"sensor_silent": {"hours": 6, "hysteresis_hours": 8}})", "alarms.sensor_silent.hysteresis_hours"},
      {R"({"overdue": {"severity": "urgent"}})", "alarms.overdue.severity"},
      {R"({"gateway_offline": {"enabled": "yes"}})", "enabled"},
      {R"({"unsupported": 3})", "alarms.unsupported must be an object"},
      {"[]", "\"alarms\" must be an object"},
  };
  for (const auto& [setting, needle] : bad) {
    const std::string error = with(setting);
    CHECK_TEXT(error.find(needle) != std::string::npos, (std::string(setting) + " -> " + error).c_str());
  }
}

// core::WriteBundle is the inverse of LoadBundle: what it writes loads back the same (site, radio
// addresses, readings, operations with a missing value, scans, the map's arrays), and the output
// folder must be new or empty.
TEST(Bundle, WrittenBundleLoadsBackTheSame) {
  lw::test::WriteBundle(dir, "time,sensor_id,thickness_mm\n2026-01-02T00:00:00Z,1001,119\n2026-01-03T00:00:00Z,1002,118.5\n");
  dir.Write("operations.csv", "time,throughput_tph,ore_ai\n2026-01-01T00:00:00Z,3500,\n2026-01-02T00:00:00Z,3400,0.3\n");
  dir.Write("scans/scan_2026-02-01.xyz", "1.01 0 0.5\n0 1.02 1.5\n");
  Bundle a = LoadBundle(dir.path());
  a.crusher.site = "north-pit";
  a.crusher.sensors[1].address = 0x0013A20040FFEE01ull;
  a.map.wear_stderr = a.map.wear * 0.1;
  lw::test::TempDirectory out("lw-bundle-out");
  const auto target = out.path() / "copy";
  WriteBundle(a, target, {{"notes.txt", "kept\n"}});
  const Bundle b = LoadBundle(target);
  STRCMP_EQUAL("north-pit", b.crusher.site.c_str());
  CHECK(b.crusher.installed_at == a.crusher.installed_at);
  LONGS_EQUAL(a.crusher.rows.size(), b.crusher.rows.size());
  STRCMP_EQUAL(a.crusher.rows[1].name.c_str(), b.crusher.rows[1].name.c_str());
  CHECK_FALSE(b.crusher.sensors[0].address.has_value());
  CHECK(b.crusher.sensors[1].address == a.crusher.sensors[1].address);
  LONGS_EQUAL(a.readings.size(), b.readings.size());
  for (size_t i = 0; i < a.readings.size(); ++i) {
    STRCMP_EQUAL(a.readings[i].sensor_id.c_str(), b.readings[i].sensor_id.c_str());
    CHECK(a.readings[i].time == b.readings[i].time);
    DOUBLES_EQUAL(a.readings[i].thickness_mm, b.readings[i].thickness_mm, 0);
  }
  LONGS_EQUAL(2, b.operations.size());
  CHECK_FALSE(b.operations[0].ore_ai.has_value());
  DOUBLES_EQUAL(0.3, *b.operations[1].ore_ai, 1e-12);
  CHECK_FALSE(b.operations[1].power_kw.has_value());
  LONGS_EQUAL(1, b.scans.size());
  CHECK(b.scans[0].date == a.scans[0].date);
  LONGS_EQUAL(2, b.scans[0].points.size());
  DOUBLES_EQUAL(1.02, b.scans[0].points[1].y(), 1e-9);
  LONGS_EQUAL(a.map.face_count(), b.map.face_count());
  CHECK(b.map.wear.isApprox(a.map.wear, 1e-9));
  CHECK(b.map.has_wear_stderr());
  CHECK(b.map.wear_stderr.isApprox(a.map.wear_stderr, 1e-9));
  CHECK_TRUE(std::filesystem::exists(target / "notes.txt"));
  // Only the bundle is left: no temporary folder beside it.
  LONGS_EQUAL(1, std::distance(std::filesystem::directory_iterator(out.path()), std::filesystem::directory_iterator()));
  // A folder that holds something is never written into.
  CHECK_THROWS(std::runtime_error, WriteBundle(a, target));
  CHECK_TRUE(std::filesystem::exists(target / "notes.txt"));
}
