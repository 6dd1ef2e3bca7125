// Alarms (docs/alarms.md): the engine over a real SQLite file (raise and clear with hysteresis,
// states, a restart), and its REST routes through the real HTTP server on loopback.
#include <chrono>
#include <cmath>
#include <string>

#include "core/time.hpp"
#include "unit/server/http_fixture.hpp"

#include <CppUTest/TestHarness.h>  // last: its leak-detection macros clash with std headers

using namespace lw::server;
using nlohmann::json;

namespace {
lw::test::CrusherFolder& Folder() {
  return lw::test::HttpFolder();
}
const char* kReadToken = lw::test::ServerParts::kReadToken;
const char* kWriteToken = lw::test::ServerParts::kWriteToken;
constexpr int64_t kT0 = 1'800'000'000;  // "now" of the evaluations (2027)

std::string Id() {
  return Folder().id();
}
double Threshold() {
  return Folder().bundle.crusher.thickness_min_mm + 10;  // thinnest_area's default
}

/// A wear state whose liner's thinnest area is `mm` (supported or not).
CrusherState Thin(double mm, bool supported = true) {
  CrusherState st;
  st.has_wear = true;
  st.reconstruction.status = lw::core::kStatusOk;
  st.areas.liner.thickness_mm = mm;
  st.areas.liner.lo_mm = mm - 3;
  st.areas.liner.hi_mm = mm + 3;
  st.areas.liner.supported = supported;
  st.areas.liner.row = Folder().bundle.crusher.rows.front().name;
  return st;
}

AlarmInputs Inputs(int64_t now_s, const CrusherState* st) {
  AlarmInputs in;
  in.now_s = now_s;
  in.wear = st;
  return in;
}

lw::core::TimePoint At(int64_t s) {
  return lw::core::TimePoint(std::chrono::seconds(s));
}

size_t CountOf(const std::vector<AlarmRecord>& alarms, const std::string& rule) {
  size_t n = 0;
  for (const AlarmRecord& a : alarms) n += a.rule == rule;
  return n;
}
}  // namespace

TEST_GROUP(Alarms){};

// A thinnest area going back and forth across its threshold raises one alarm, held until the area is
// back past the hysteresis; the same readings with the hysteresis set to 0 raise a new alarm at each dip.
TEST(Alarms, ThinnestAreaAtTheEdgeRaisesOnceAndClearsOnlyPastTheHysteresis) {
  lw::test::ServerParts p(Folder().crushers, false);
  const double t = Threshold();
  int64_t now = kT0;
  const auto feed = [&](double mm, bool supported = true) {
    const CrusherState st = Thin(mm, supported);
    p.alarms->Evaluate(Id(), Inputs(now += 600, &st));
    return p.alarms->Open(Id());
  };
  CHECK(feed(t + 0.5).empty());
  const std::vector<AlarmRecord> raised = feed(t - 0.1);
  LONGS_EQUAL(1, raised.size());
  STRCMP_EQUAL("thinnest_area", raised[0].rule.c_str());
  STRCMP_EQUAL("active", raised[0].state.c_str());
  STRCMP_EQUAL("warning", raised[0].severity.c_str());
  DOUBLES_EQUAL(t - 0.1, raised[0].value.value_or(0), 1e-9);
  for (const double mm : {t + 0.1, t - 0.1, t + 1.9, t - 0.05, t + 1.99}) {
    const std::vector<AlarmRecord> open = feed(mm);
    LONGS_EQUAL_TEXT(1, open.size(), std::to_string(mm).c_str());
    LONGS_EQUAL(raised[0].id, open[0].id);
  }
  LONGS_EQUAL(1, feed(t - 20, false).size());  // an unsupported number neither raises nor clears
  LONGS_EQUAL(1, feed(t + 20, false).size());
  CHECK(feed(t + 2.0).empty());
  CHECK(feed(t + 1.0).empty());  // inside the band after the clear: none raised
  const std::vector<AlarmRecord> again = feed(t - 0.5);
  LONGS_EQUAL(1, again.size());
  CHECK(again[0].id != raised[0].id);
  const std::vector<AlarmRecord> stored = p.alarms->List(Id(), "", 0, 100);
  LONGS_EQUAL(2, stored.size());
  STRCMP_EQUAL("cleared", stored[1].state.c_str());
  // Without hysteresis the edge flaps: back above the threshold clears, the next dip raises anew.
  p.alarms->UpdateRules(Id(), {{"thinnest_area", {{"hysteresis_mm", 0}}}}, "test", now);
  CHECK(feed(t + 0.1).empty());
  LONGS_EQUAL(1, feed(t - 0.1).size());
  LONGS_EQUAL(3, p.alarms->List(Id(), "", 0, 100).size());
}

// Open alarms, their acknowledgement and the audit trail are in the database: a restarted engine
// has the same alarms, raises none of them again on the same inputs, and clears them as before.
TEST(Alarms, ARestartKeepsEveryAlarmAndRaisesNoneTwice) {
  lw::test::TempDirectory keep{"lw-alarms"};
  const std::string db = keep.File("db.sqlite");
  const CrusherState st = Thin(Threshold() - 1);
  AlarmInputs in = Inputs(kT0, &st);
  const std::string sensor = Folder().bundle.crusher.sensors.front().id;
  in.sensors = {{sensor, kT0 - 3600, 3200}};
  int64_t battery_id = 0;
  {
    lw::test::ServerParts p(Folder().crushers, false, "", db);
    CHECK_TRUE(p.alarms->Evaluate(Id(), in));
    const std::vector<AlarmRecord> open = p.alarms->Open(Id());
    LONGS_EQUAL(2, open.size());
    for (const AlarmRecord& a : open) {
      if (a.rule != "battery_low") continue;
      battery_id = a.id;
      STRCMP_EQUAL(sensor.c_str(), a.subject.c_str());
    }
    CHECK(battery_id > 0);
    AlarmRecord acked;
    CHECK(p.alarms->Acknowledge(Id(), battery_id, "ops", kT0 + 60, &acked) == AlarmEngine::Ack::kAcknowledged);
  }
  {
    lw::test::ServerParts p(Folder().crushers, false, "", db);
    const std::vector<AlarmRecord> open = p.alarms->Open(Id());
    LONGS_EQUAL(2, open.size());
    for (const AlarmRecord& a : open) {
      if (a.id != battery_id) continue;
      STRCMP_EQUAL("acknowledged", a.state.c_str());
      STRCMP_EQUAL("ops", a.acknowledged_by.c_str());
      LONGS_EQUAL(kT0 + 60, a.acknowledged_s.value_or(0));
    }
    // No wear computed yet and no sensor data after the restart: held, not cleared (nor raised again).
    CHECK_FALSE(p.alarms->Evaluate(Id(), Inputs(kT0 + 100, nullptr)));
    in.now_s = kT0 + 120;
    CHECK_FALSE(p.alarms->Evaluate(Id(), in));  // the same conditions: nothing new
    LONGS_EQUAL(2, p.alarms->List(Id(), "", 0, 100).size());
    in.sensors[0].battery_mv = 3350;  // inside the hysteresis: held
    CHECK_FALSE(p.alarms->Evaluate(Id(), in));
    in.sensors[0].battery_mv = 3400;
    CHECK_TRUE(p.alarms->Evaluate(Id(), in));
    LONGS_EQUAL(1, p.alarms->Open(Id()).size());
  }
  lw::test::ServerParts p(Folder().crushers, false, "", db);
  LONGS_EQUAL(1, p.alarms->Open(Id()).size());
  const std::vector<AlarmRecord> cleared = p.alarms->List(Id(), "cleared", 0, 100);
  LONGS_EQUAL(1, cleared.size());
  LONGS_EQUAL(battery_id, cleared[0].id);
  LONGS_EQUAL(kT0 + 120, cleared[0].cleared_s.value_or(0));
  const std::vector<AlarmAuditEntry> audit = p.alarms->Audit(battery_id);
  LONGS_EQUAL(3, audit.size());
  STRCMP_EQUAL("raised", audit[0].action.c_str());
  STRCMP_EQUAL("acknowledged", audit[1].action.c_str());
  STRCMP_EQUAL("ops", audit[1].by.c_str());
  STRCMP_EQUAL("cleared", audit[2].action.c_str());
  AlarmRecord out;
  CHECK(p.alarms->Acknowledge(Id(), battery_id, "ops", kT0 + 200, &out) == AlarmEngine::Ack::kCleared);
  CHECK(p.alarms->Acknowledge(Id(), 999999, "ops", kT0 + 200, &out) == AlarmEngine::Ack::kUnknown);
}

// Each of the other rules raises past its threshold, holds inside its hysteresis and clears past
// it; a disabled rule clears its alarms.
TEST(Alarms, EveryRuleRaisesHoldsAndClears) {
  lw::test::ServerParts p(Folder().crushers, false);
  const lw::core::CrusherConfig& cfg = Folder().bundle.crusher;
  CrusherState st = Thin(cfg.thickness_new_mm);
  lw::core::RowForecast rf;
  rf.row = cfg.rows.front().name;
  rf.ok = true;
  rf.min_thickness_mm = cfg.thickness_min_mm + 20;
  rf.reach_earliest = At(kT0 + 20 * 86400);
  st.row_forecasts = {rf};
  AlarmInputs in = Inputs(kT0, &st);
  const auto open = [&](const std::string& rule) {
    p.alarms->Evaluate(Id(), in);
    return CountOf(p.alarms->Open(Id()), rule);
  };
  LONGS_EQUAL(1, open("reline_due"));  // 20 days <= 30
  st.row_forecasts[0].reach_earliest = At(kT0 + 31 * 86400);
  LONGS_EQUAL(1, open("reline_due"));  // within 30 + 2
  st.row_forecasts[0].reach_earliest = At(kT0 + 33 * 86400);
  LONGS_EQUAL(0, open("reline_due"));
  st.row_forecasts[0].below_minimum_since = At(kT0 - 86400);
  st.row_forecasts[0].min_thickness_mm = cfg.thickness_min_mm - 1;
  LONGS_EQUAL(1, open("overdue"));
  CHECK(p.alarms->Open(Id()).back().severity == "critical");
  st.row_forecasts[0].below_minimum_since.reset();
  st.row_forecasts[0].min_thickness_mm = cfg.thickness_min_mm + 1;  // above, not past the 2 mm
  LONGS_EQUAL(1, open("overdue"));
  st.row_forecasts[0].min_thickness_mm = cfg.thickness_min_mm + 2;
  LONGS_EQUAL(0, open("overdue"));

  in.sensors = {{cfg.sensors.front().id, kT0 - 25 * 3600, 3600}};
  LONGS_EQUAL(1, open("sensor_silent"));
  in.sensors[0].latest_s = kT0 - 13 * 3600;  // silent 13 h: more than 24 - 12
  LONGS_EQUAL(1, open("sensor_silent"));
  in.sensors[0].latest_s = kT0 - 11 * 3600;
  LONGS_EQUAL(0, open("sensor_silent"));

  p.alarms->GatewayStatus(Id(), "gw1", false, kT0 - 5 * 60);
  LONGS_EQUAL(0, open("gateway_offline"));  // offline for 5 of 10 minutes
  in.now_s = kT0 + 6 * 60;
  LONGS_EQUAL(1, open("gateway_offline"));
  p.alarms->GatewayStatus(Id(), "gw1", true, kT0 + 7 * 60);
  LONGS_EQUAL(0, open("gateway_offline"));

  in.rejected_total = 11;  // 11 since the first count, 6 minutes ago
  LONGS_EQUAL(1, open("rejected_rate"));
  in.now_s += 3700;
  in.rejected_total = 14;  // 3 in the last hour
  LONGS_EQUAL(0, open("rejected_rate"));

  st.setting.ring.supported = true;
  st.setting.opening_mm = 30;  // above the default 20 mm, but the rule is off until enabled
  LONGS_EQUAL(0, open("setting_open"));
  p.alarms->UpdateRules(Id(), {{"setting_open", {{"enabled", true}}}}, "test", in.now_s);
  LONGS_EQUAL(1, open("setting_open"));
  STRCMP_CONTAINS("raise the mantle", p.alarms->Open(Id()).back().detail.c_str());
  st.setting.opening_mm = 19;  // within 20 - 2
  LONGS_EQUAL(1, open("setting_open"));
  st.setting.ring.supported = false;  // an unsupported opening neither raises nor clears
  st.setting.opening_mm = 0;
  LONGS_EQUAL(1, open("setting_open"));
  st.setting.ring.supported = true;
  st.setting.opening_mm = 18;
  LONGS_EQUAL(0, open("setting_open"));
  // A measured setting restarts the count: opened 31 mm since installation, but 3 since the CSS
  // was measured at an opening of 28 (after raising the mantle) clears; 23 since raises again.
  st.setting.opening_mm = 31;
  LONGS_EQUAL(1, open("setting_open"));
  st.setting.check = lw::core::SettingCheck{lw::core::TimePoint(std::chrono::seconds(kT0)), 125, 28, "ops"};
  LONGS_EQUAL(0, open("setting_open"));
  st.setting.opening_mm = 51;
  LONGS_EQUAL(1, open("setting_open"));
  STRCMP_CONTAINS("opened 23.0 mm", p.alarms->Open(Id()).back().detail.c_str());
  STRCMP_CONTAINS("since it was measured on", p.alarms->Open(Id()).back().detail.c_str());
  // A check whose ring was not supported then keeps its central estimate: the count goes on from it
  // (it clears at 3 mm since) and the detail says what the opening then is.
  st.setting.check->opening_supported = false;
  st.setting.opening_mm = 31;
  LONGS_EQUAL(0, open("setting_open"));
  st.setting.opening_mm = 51;
  LONGS_EQUAL(1, open("setting_open"));
  STRCMP_CONTAINS("central estimate of a ring not supported then", p.alarms->Open(Id()).back().detail.c_str());
  // An opening at the check not known (no reading of the liner up to it) neither raises nor clears.
  st.setting.check->opening_mm = std::nan("");
  st.setting.opening_mm = 18;
  LONGS_EQUAL(1, open("setting_open"));
  st.setting.check.reset();
  st.setting.opening_mm = 18;
  LONGS_EQUAL(0, open("setting_open"));

  st.reconstruction.status = lw::core::kStatusUnsupported;
  LONGS_EQUAL(1, open("unsupported"));
  p.alarms->UpdateRules(Id(), {{"unsupported", {{"enabled", false}}}}, "test", in.now_s);
  LONGS_EQUAL(0, open("unsupported"));
}

namespace {
struct Api : lw::test::LiveApi {
  explicit Api(const std::string& db = "") : LiveApi(Folder().crushers, true, "", db) {}
  std::string Base() const { return "/api/v1/crushers/" + Id() + "/alarms"; }
  std::pair<int, json> Get(const std::string& path, const char* token = kReadToken) const {
    auto res = Client(token).Get(Base() + path);
    CHECK(res);
    return {res->status, json::parse(res->body)};
  }
  std::pair<int, json> Post(const std::string& path, const std::string& body, const char* token = kWriteToken) const {
    auto res = Client(token).Post(Base() + path, body, "application/json");
    CHECK(res);
    return {res->status, json::parse(res->body)};
  }
};
}  // namespace

TEST(Alarms, RestListsAcknowledgesOnceAndRefusesWhatItCannotDo) {
  Api a;
  const int64_t now = 4'000'000'000 - 3600;  // an hour before the fixture's clock: "recent"
  const CrusherState low = Thin(Threshold() - 1);
  a.parts.alarms->Evaluate(Id(), Inputs(now, &low));
  auto [status, list] = a.Get("");
  LONGS_EQUAL_TEXT(200, status, list.dump().c_str());
  LONGS_EQUAL(1, list["alarms"].size());
  const json alarm = list["alarms"][0];
  STRCMP_EQUAL("active", alarm["state"].get<std::string>().c_str());
  STRCMP_EQUAL("raised", alarm["audit"][0]["action"].get<std::string>().c_str());
  const std::string ack = "/" + std::to_string(alarm["id"].get<int64_t>()) + "/ack";
  LONGS_EQUAL(400, a.Get("?state=open").first);
  CHECK(a.Get("?state=open").second["error"].get<std::string>().find("state") != std::string::npos);
  LONGS_EQUAL(0, a.Get("?state=cleared").second["alarms"].size());
  LONGS_EQUAL(403, a.Post(ack, "", kReadToken).first);
  auto [acked, body] = a.Post(ack, "");
  LONGS_EQUAL_TEXT(200, acked, body.dump().c_str());
  STRCMP_EQUAL("acknowledged", body["state"].get<std::string>().c_str());
  STRCMP_EQUAL("writer", body["acknowledged_by"].get<std::string>().c_str());
  auto [again, same] = a.Post(ack, "");
  LONGS_EQUAL(200, again);
  CHECK(same["acknowledged_at"] == body["acknowledged_at"]);
  LONGS_EQUAL(2, same["audit"].size());  // raised, acknowledged: once
  LONGS_EQUAL(404, a.Post("/999999/ack", "").first);
  LONGS_EQUAL(404, a.Post("/abc/ack", "").first);
  const CrusherState fine = Thin(Threshold() + 5);
  a.parts.alarms->Evaluate(Id(), Inputs(now + 60, &fine));
  auto [conflict, err] = a.Post(ack, "");
  LONGS_EQUAL(409, conflict);
  CHECK(err["error"].get<std::string>().find("cleared") != std::string::npos);
  LONGS_EQUAL(1, a.Get("?state=cleared").second["alarms"].size());
}

TEST(Alarms, RulesChangeOverRestSurviveARestartAndBadKeysAreRefusedByName) {
  lw::test::TempDirectory keep{"lw-alarm-rules"};
  const std::string db = keep.File("db.sqlite");
  {
    Api a(db);
    auto [status, rules] = a.Get("/rules");
    LONGS_EQUAL(200, status);
    DOUBLES_EQUAL(3300, rules["rules"]["battery_low"]["below_mv"].get<double>(), 0);
    LONGS_EQUAL(403, a.Post("/rules", R"({"battery_low": {"below_mv": 3100}})", kReadToken).first);
    auto [set, now] = a.Post("/rules", R"({"battery_low": {"below_mv": 3100}})");
    LONGS_EQUAL_TEXT(200, set, now.dump().c_str());
    DOUBLES_EQUAL(3100, now["rules"]["battery_low"]["below_mv"].get<double>(), 0);
    DOUBLES_EQUAL(100, now["rules"]["battery_low"]["hysteresis_mv"].get<double>(), 0);
    for (const char* bad : {R"({"battery_low": {"below_mv": -1}})", R"({"battery_low": {"below": 1}})", R"({"nope": {}})", "x"}) {
      auto [refused, err] = a.Post("/rules", bad);
      LONGS_EQUAL_TEXT(400, refused, bad);
      CHECK_TEXT(err["error"].get<std::string>().find(std::string(bad) == "x" ? "JSON" : "alarms.") != std::string::npos,
                 err.dump().c_str());
    }
    auto [set2, later] = a.Post("/rules", R"({"battery_low": {"severity": "critical"}})");
    LONGS_EQUAL(200, set2);
    DOUBLES_EQUAL(3100, later["rules"]["battery_low"]["below_mv"].get<double>(), 0);  // the earlier change kept
  }
  Api a(db);
  const json rules = a.Get("/rules").second["rules"];
  DOUBLES_EQUAL(3100, rules["battery_low"]["below_mv"].get<double>(), 0);
  STRCMP_EQUAL("critical", rules["battery_low"]["severity"].get<std::string>().c_str());
}

// A rules body nested 30,000 deep (60 KB, within the route's 64 KiB) is refused before it is
// parsed: the merge copied the nested value, one stack frame per level, and overflowed the worker
// thread's stack (a hand-made input that crashed fuzz_rest_bodies, which keeps it as
// fuzz/corpus/rest_bodies/crash-rules-nested-30000).
TEST(Alarms, ARulesBodyNestedTooDeeplyIsRefusedAndChangesNothing) {
  Api a;
  const std::string deep = std::string(30'000, '[') + std::string(30'000, ']');
  for (const std::string& body : {R"({"battery_low": )" + deep + "}", R"({"battery_low": {"below_mv": )" + deep + "}}"}) {
    auto [refused, err] = a.Post("/rules", body);
    LONGS_EQUAL(400, refused);
    STRCMP_EQUAL("body is nested too deeply", err["error"].get<std::string>().c_str());
  }
  // Nesting a rules body has (rule, setting, value) and a little more is still parsed and judged.
  auto [bad, err] = a.Post("/rules", R"({"battery_low": {"below_mv": [[[[[1]]]]]}})");
  LONGS_EQUAL(400, bad);
  CHECK_TEXT(err["error"].get<std::string>().find("alarms.battery_low") != std::string::npos, err.dump().c_str());
  DOUBLES_EQUAL(3300, a.Get("/rules").second["rules"]["battery_low"]["below_mv"].get<double>(), 0);
}
