// Relines through the real HTTP server on loopback and a real SQLite file (docs/server.md).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <tuple>

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

/// The demo folder's server on 127.0.0.1 over the database `db` (empty: a fresh one), with tokens.
struct Api : lw::test::LiveApi {
  explicit Api(const std::string& db = "") : LiveApi(Folder().crushers, true, "", db) {}
  httplib::Client Client(const char* token = kWriteToken) const { return LiveApi::Client(token); }
  std::string Base() const { return "/api/v1/crushers/" + Folder().id(); }
  void LoadAll() const { LONGS_EQUAL(200, PostReadings(Folder(), kWriteToken)); }
  /// POSTs a reline; returns (status, body).
  std::pair<int, json> Reline(const json& body, const char* token = kWriteToken) {
    auto res = Client(token).Post(Base() + "/relines", body.dump(), "application/json");
    CHECK(res);
    return {res->status, json::parse(res->body)};
  }
  json Campaigns() {
    auto res = Client(kReadToken).Get(Base() + "/campaigns");
    CHECK(res);
    LONGS_EQUAL_TEXT(200, res->status, res->body.c_str());
    return json::parse(res->body)["campaigns"];
  }
  json Wear() {
    auto res = Client(kReadToken).Get(Base() + "/wear");
    CHECK(res);
    LONGS_EQUAL_TEXT(200, res->status, res->body.c_str());
    return json::parse(res->body);
  }
};

std::string Day(double days) {
  const auto t = Folder().bundle.crusher.installed_at +
                 std::chrono::duration_cast<lw::core::TimePoint::duration>(std::chrono::duration<double>(days * 86400.0));
  return lw::core::FormatIsoTime(t);
}
}  // namespace

TEST_GROUP(Campaigns){};

TEST(Campaigns, RelineKeepsHistoryAcrossRestartsAndWearUsesOnlyTheNewLiner) {
  const double old_new = Folder().bundle.crusher.thickness_new_mm;
  const double fresh = old_new + 15;
  lw::test::TempDirectory keep{"lw-campaigns"};  // the database outlives the first server
  const std::string db = keep.File("db.sqlite");
  {
    Api a(db);
    a.LoadAll();
    LONGS_EQUAL(1, a.Campaigns().size());
    auto [status, made] = a.Reline({{"time", Day(12)}, {"thickness_new_mm", fresh}, {"scan_xyz", "0 0 1\n0.1 0 1.2\n"}});
    LONGS_EQUAL_TEXT(201, status, made.dump().c_str());
    DOUBLES_EQUAL(fresh, made["thickness_new_mm"].get<double>(), 1e-9);
    CHECK(made["end"].is_null());
    // The same time again: the campaign it started, not a third one.
    auto [again, same] = a.Reline({{"time", Day(12)}, {"thickness_new_mm", fresh}});
    LONGS_EQUAL(200, again);
    CHECK(same["start"] == made["start"]);
    const json list = a.Campaigns();
    LONGS_EQUAL(2, list.size());
    CHECK(list[0]["end"] == made["start"]);
    CHECK_TRUE(list[0]["has_scan"].get<bool>());
    CHECK_FALSE(list[1]["has_scan"].get<bool>());
    CHECK(list[1]["end"].is_null());
    // Only the readings after the reline count, against the new thickness.
    const json after = a.Wear();
    CHECK(after["readings_used"].size() > 0);
    for (const auto& r : after["readings_used"]) CHECK_TEXT(r["time"].get<std::string>() >= Day(12), r.dump().c_str());
    double max = 0;
    for (const auto& v : after["remaining_mm"]) max = std::max(max, v.get<double>());
    CHECK(max <= fresh + 1e-6);
    // (The simulated boards keep reporting the old liner after the reline, so the new liner's wear is
    // large here: only which readings count and against which thickness is checked.)
  }
  {
    Api a(db);  // a restart on the same database
    json list = a.Campaigns();
    LONGS_EQUAL(2, list.size());
    CHECK_TRUE(list[0]["has_scan"].get<bool>());
    DOUBLES_EQUAL(fresh, list[1]["thickness_new_mm"].get<double>(), 1e-9);
    // The restarted server applies the stored campaign: only the new liner's readings count.
    const json wear = a.Wear();
    CHECK(wear["readings_used"].size() > 0);
    for (const auto& r : wear["readings_used"]) CHECK_TEXT(r["time"].get<std::string>() >= Day(12), r.dump().c_str());
    auto [status, made] = a.Reline({{"time", Day(16)}, {"thickness_new_mm", old_new}});
    LONGS_EQUAL_TEXT(201, status, made.dump().c_str());
    const json three = a.Campaigns();
    LONGS_EQUAL(3, three.size());
    CHECK(three[0] == list[0]);
    CHECK_TRUE(three[0]["has_scan"].get<bool>());
    CHECK(three[1]["start"] == list[1]["start"]);
    CHECK(three[1]["end"] == made["start"]);
  }
}

TEST(Campaigns, BadRelinesNameTheFieldAndChangeNothing) {
  Api a;
  a.LoadAll();
  const double t = Folder().bundle.crusher.thickness_new_mm;
  const json before = a.Campaigns();
  struct Case {
    json body;
    const char* field;
  };
  const Case cases[] = {
      {{{"time", "yesterday"}, {"thickness_new_mm", t}}, "time"},
      {{{"time", Day(-30)}, {"thickness_new_mm", t}}, "time"},
      {{{"time", "2200-01-01T00:00:00Z"}, {"thickness_new_mm", t}}, "time"},
      {{{"time", Day(5)}, {"thickness_new_mm", -3}}, "thickness_new_mm"},
      {{{"time", Day(5)}}, "thickness_new_mm"},
      {{{"time", Day(5)}, {"thickness_new_mm", t}, {"scan_xyz", "0 0 1\n0 zero 1\n"}}, "scan_xyz:2"},
      {{{"time", Day(5)}, {"thickness_new_mm", t}, {"sensors", json::array({{{"id", "x"}}})}}, "sensors"},
  };
  for (const Case& c : cases) {
    auto [status, err] = a.Reline(c.body);
    CHECK_TEXT(status == 400 || status == 422, c.body.dump().c_str());
    const std::string msg = err["error"].get<std::string>();
    CHECK_TEXT(msg.find(c.field) != std::string::npos, (c.body.dump() + " -> " + msg).c_str());
  }
  CHECK(a.Campaigns() == before);
  // Write scope: a reader is refused and nothing changes.
  auto [status, err] = a.Reline({{"time", Day(5)}, {"thickness_new_mm", t}}, kReadToken);
  LONGS_EQUAL(403, status);
  CHECK(a.Campaigns() == before);
}

// The old liner's end-of-life scan posted with the reline is the new liner's prior for the wear
// pattern (docs/wear.md, *Earlier campaigns*), in the wear JSON's "scan", and still after a restart.
TEST(Campaigns, TheRelinesEndOfLifeScanIsTheNewLinersPrior) {
  const lw::core::WearMap& map = Folder().bundle.map;
  // A worn surface: each face's centroid moved outward by a wear that grows towards the discharge.
  std::string scan;
  char line[96];
  for (size_t i = 0; i < map.centroids.size(); ++i) {
    const double wear_m = 0.001 * (10.0 + 40.0 * std::exp(-map.z[static_cast<Eigen::Index>(i)]));
    const Eigen::Vector3d p = map.centroids[i] - wear_m * map.normals[i];
    std::snprintf(line, sizeof line, "%.6f %.6f %.6f\n", p.x(), p.y(), p.z());
    scan += line;
  }
  // The folder without its scan (a scan of the new liner would win over the prior).
  lw::test::TempDirectory keep{"lw-campaigns-prior"};
  const std::string db = keep.File("db.sqlite"), crushers = keep.File("crushers");
  std::filesystem::create_directories(crushers + "/demo");
  for (const char* file : {"crusher.json", "wear_map.vtk"})
    std::filesystem::copy_file(Folder().folder + "/" + file, crushers + "/demo/" + file);
  struct Served : lw::test::LiveApi {
    Served(const std::string& dir, const std::string& db) : LiveApi(dir, true, "", db) {}
    json Wear() const {
      auto res = Client(kReadToken).Get("/api/v1/crushers/" + Folder().id() + "/wear?faces=false");
      CHECK(res);
      LONGS_EQUAL_TEXT(200, res->status, res->body.c_str());
      return json::parse(res->body);
    }
  };
  const auto check_prior = [](const json& wear) {
    CHECK_TEXT(wear["scan"].is_object(), wear["scan"].dump().c_str());
    CHECK_TEXT(wear["scan"].contains("prior_campaign"), wear["scan"].dump().c_str());
    CHECK(wear["scan"]["applied"].get<bool>());
    CHECK(wear["scan"]["file"].get<std::string>().find("the reline's end-of-life scan") != std::string::npos);
    CHECK(wear["scan"]["pattern_change_relative"].get<double>() > 0);
  };
  {
    Served a(crushers, db);
    LONGS_EQUAL(200, a.PostReadings(Folder(), kWriteToken));
    CHECK_TRUE(a.Wear()["scan"].is_null());  // no scan yet
    const json body = {{"time", Day(12)}, {"thickness_new_mm", Folder().bundle.crusher.thickness_new_mm}, {"scan_xyz", scan}};
    auto res = a.Client(kWriteToken).Post("/api/v1/crushers/" + Folder().id() + "/relines", body.dump(), "application/json");
    CHECK(res);
    LONGS_EQUAL_TEXT(201, res->status, res->body.c_str());
    check_prior(a.Wear());
  }
  Served restarted(crushers, db);
  check_prior(restarted.Wear());

  // Without scan_xyz: the folder's scan taken during the closed campaign is the prior, found in
  // the folder (its path relative to it), live and after a restart.
  const std::string scan_file = "scans/scan_" + Day(10).substr(0, 10) + ".xyz";
  std::filesystem::create_directories(crushers + "/demo/scans");
  std::ofstream(crushers + "/demo/" + scan_file) << scan;
  const std::string db2 = keep.File("db2.sqlite");
  const auto check_folder_prior = [&](const json& wear) {
    CHECK_TEXT(wear["scan"].contains("prior_campaign"), wear["scan"].dump().c_str());
    STRCMP_EQUAL(scan_file.c_str(), wear["scan"]["file"].get<std::string>().c_str());
    CHECK(wear["scan"]["applied"].get<bool>());
  };
  {
    Served a(crushers, db2);
    LONGS_EQUAL(200, a.PostReadings(Folder(), kWriteToken));
    const json body = {{"time", Day(12)}, {"thickness_new_mm", Folder().bundle.crusher.thickness_new_mm}};
    auto res = a.Client(kWriteToken).Post("/api/v1/crushers/" + Folder().id() + "/relines", body.dump(), "application/json");
    CHECK(res);
    LONGS_EQUAL_TEXT(201, res->status, res->body.c_str());
    check_folder_prior(a.Wear());
  }
  Served again(crushers, db2);
  check_folder_prior(again.Wear());
}

// A reline posted by mistake is voided (docs/campaigns.md, *Voiding a reline*): kept in the list,
// marked voided by the token's name, and the campaign it closed runs again; the wear and the
// forecast are what they were before the mistake, live and after a restart.
TEST(Campaigns, AVoidedRelineIsKeptAndTheCampaignItClosedRunsAgainAcrossARestart) {
  const double fresh = Folder().bundle.crusher.thickness_new_mm + 15;
  lw::test::TempDirectory keep{"lw-campaigns-void"};
  const std::string db = keep.File("db.sqlite");
  const auto wear = [](Api& a) {
    json w = a.Wear();
    w.erase("computed_at");
    return w;
  };
  const auto forecast = [](Api& a) {
    auto res = a.Client(kReadToken).Get(a.Base() + "/forecast");
    CHECK(res);
    LONGS_EQUAL_TEXT(200, res->status, res->body.c_str());
    json f = json::parse(res->body);
    f.erase("computed_at");
    return f;
  };
  // What identifies a campaign (a running one's life_days counts to now).
  const auto same = [](const json& x, const json& y) {
    for (const char* k : {"start", "end", "running", "thickness_new_mm", "has_scan", "sensors", "final_readings"})
      CHECK_TEXT(x[k] == y[k], (std::string(k) + ": " + x.dump().substr(0, 300) + " vs " + y.dump().substr(0, 300)).c_str());
  };
  const auto post_void = [](Api& a, const std::string& time, const json& body, const char* token = kWriteToken) {
    auto res = a.Client(token).Post(a.Base() + "/relines/" + time + "/void", body.dump(), "application/json");
    CHECK(res);
    return std::pair<int, json>(res->status, json::parse(res->body));
  };
  json list_before, wear_before, forecast_before;
  std::string voided_at;
  const auto check_restored = [&](Api& a) {
    const json list = a.Campaigns();
    LONGS_EQUAL(3, list.size());
    same(list[0], list_before[0]);
    same(list[1], list_before[1]);
    CHECK_TRUE(list[1]["running"].get<bool>());
    CHECK_TRUE(list[2]["voided"].get<bool>());
    CHECK_FALSE(list[2]["running"].get<bool>());
    CHECK(list[2]["start"] == Day(16));
    STRCMP_EQUAL("writer", list[2]["voided_by"].get<std::string>().c_str());
    STRCMP_EQUAL("the crew relined on paper only", list[2]["void_reason"].get<std::string>().c_str());
    CHECK(list[2]["voided_at"] == voided_at);
    CHECK_TRUE(list[2]["life_days"].is_null());
    CHECK_TEXT(wear(a) == wear_before, "the wear is not the one before the mistaken reline");
    CHECK_TEXT(forecast(a) == forecast_before, "the forecast is not the one before the mistaken reline");
  };
  {
    Api a(db);
    a.LoadAll();
    LONGS_EQUAL(201, a.Reline({{"time", Day(12)}, {"thickness_new_mm", fresh}, {"scan_xyz", "0 0 1\n0.1 0 1.2\n"}}).first);
    list_before = a.Campaigns();
    wear_before = wear(a);
    forecast_before = forecast(a);
    // The mistake: a second reline that did not happen.
    auto [status, made] = a.Reline({{"time", Day(16)}, {"thickness_new_mm", fresh + 7}, {"scan_xyz", "0 0 1\n"}});
    LONGS_EQUAL_TEXT(201, status, made.dump().c_str());
    CHECK(wear(a) != wear_before);
    // A reader may not void; the first campaign and a time with no reline cannot be voided.
    LONGS_EQUAL(403, post_void(a, Day(16), json::object(), kReadToken).first);
    LONGS_EQUAL(409, post_void(a, Day(12), json::object()).first);  // not the running campaign
    LONGS_EQUAL(404, post_void(a, Day(14), json::object()).first);
    LONGS_EQUAL(400, post_void(a, Day(16), {{"why", "x"}}).first);
    auto [ok, voided] = post_void(a, Day(16), {{"reason", "the crew relined on paper only"}});
    LONGS_EQUAL_TEXT(200, ok, voided.dump().c_str());
    CHECK_TRUE(voided["voided"].get<bool>());
    voided_at = voided["voided_at"].get<std::string>();
    // A void again (a retry) changes nothing.
    auto [again, same_void] = post_void(a, Day(16), json::object());
    LONGS_EQUAL(200, again);
    CHECK(same_void["voided_at"] == voided_at);
    check_restored(a);
  }
  {
    Api a(db);  // a restart on the same database
    check_restored(a);
    // The right reline at the voided one's time: a campaign of its own; the voided one stays listed.
    auto [status, made] = a.Reline({{"time", Day(16)}, {"thickness_new_mm", fresh - 5}});
    LONGS_EQUAL_TEXT(201, status, made.dump().c_str());
    const json list = a.Campaigns();
    LONGS_EQUAL(4, list.size());
    CHECK_TRUE(list[2]["voided"].get<bool>());
    CHECK(list[3]["start"] == Day(16));
    CHECK_TRUE(list[3]["running"].get<bool>());
    CHECK(list[1]["end"] == Day(16));
    DOUBLES_EQUAL(fresh - 5, list[3]["thickness_new_mm"].get<double>(), 1e-9);
  }
}

// A closed-side setting measured on the crusher (docs/wear.md, *Setting*): kept with the opening the
// server estimated at its time (as GET .../wear?at= gives it), the CSS counted from it from then on,
// the same check again harmless, bad ones refused naming the field, and all of it kept across a
// restart. The alarm side is in test_alarms.
TEST(Campaigns, AMeasuredSettingAnchorsTheCssAndSurvivesARestart) {
  lw::test::TempDirectory keep{"lw-setting"};
  const std::string db = keep.File("db.sqlite");
  const std::string at = Day(20);
  const auto post = [](Api& a, const json& body, const char* token = kWriteToken) {
    auto res = a.Client(token).Post(a.Base() + "/setting/checks", body.dump(), "application/json");
    CHECK(res);
    return std::pair<int, json>{res->status, json::parse(res->body)};
  };
  json made;
  {
    Api a(db);
    // Before the liner's first reading nothing has opened: the check's opening is 0.
    auto [early, first] = post(a, {{"time", Day(0)}, {"css_mm", 125}});
    LONGS_EQUAL_TEXT(201, early, first.dump().c_str());
    DOUBLES_EQUAL(0.0, first["opening_mm"].get<double>(), 1e-9);
    a.LoadAll();
    CHECK(a.Wear()["setting"]["checked"]["time"] == first["time"]);
    auto then = a.Client(kReadToken).Get(a.Base() + "/wear?faces=false&at=" + at);
    CHECK(then);
    const json setting_then = json::parse(then->body)["setting"];
    int status = 0;
    std::tie(status, made) = post(a, {{"time", at}, {"css_mm", 131.5}, {"note", "mantle raised 12 mm"}});
    LONGS_EQUAL_TEXT(201, status, made.dump().c_str());
    STRCMP_EQUAL("writer", made["by"].get<std::string>().c_str());
    STRCMP_EQUAL("mantle raised 12 mm", made["note"].get<std::string>().c_str());
    // The opening stored is the one the wear at that time gives (null where the ring was not supported).
    // The fixture's discharge ring must be supported at that time, or the CSS arithmetic below is
    // never checked (the unsupported branch is covered in test_core_thinnest_area).
    CHECK_TEXT(setting_then["supported"].get<bool>(), setting_then.dump().c_str());
    if (setting_then["supported"].get<bool>())
      DOUBLES_EQUAL(setting_then["opening_mm"].get<double>(), made["opening_mm"].get<double>(), 0.011);
    else
      CHECK(made["opening_mm"].is_null());
    const json setting = a.Wear()["setting"];
    DOUBLES_EQUAL(131.5, setting["checked"]["css_mm"].get<double>(), 1e-9);
    STRCMP_EQUAL(at.c_str(), setting["checked"]["time"].get<std::string>().c_str());
    if (made["opening_mm"].is_number()) {
      const double since = setting["opening_mm"].get<double>() - made["opening_mm"].get<double>();
      DOUBLES_EQUAL(since, setting["opening_since_mm"].get<double>(), 0.011);
      DOUBLES_EQUAL(131.5 + since, setting["css_mm"].get<double>(), 0.011);
      STRCMP_CONTAINS("since it was measured 132 mm on", setting["detail"].get<std::string>().c_str());
    } else {
      CHECK(setting["css_mm"].is_null());
      STRCMP_CONTAINS("the opening since is not known", setting["detail"].get<std::string>().c_str());
    }
    // A past time before the check counts from the check before it.
    auto before = a.Client(kReadToken).Get(a.Base() + "/wear?faces=false&at=" + Day(10));
    CHECK(before);
    CHECK(json::parse(before->body)["setting"]["checked"]["time"] == first["time"]);
    // The same check again: the stored one (200); another CSS at that time: 409; nothing changed.
    auto [again, same] = post(a, {{"time", at}, {"css_mm", 131.5}, {"note", "mantle raised 12 mm"}});
    LONGS_EQUAL(200, again);
    CHECK(same == made);
    struct Case {
      json body;
      int status;
      const char* names;
    } cases[] = {
        {{{"time", at}, {"css_mm", 140}}, 409, "131.5 mm is already recorded"},
        {{{"time", "2199-01-01T00:00:00Z"}, {"css_mm", 130}}, 422, "is in the future"},
        {{{"time", Day(-30)}, {"css_mm", 130}}, 422, "before the running liner's installation"},
        {{{"time", at}, {"css_mm", 0}}, 422, "\"css_mm\" 0.0 must be above 0 and at most 1000"},
        {{{"time", Day(21)}, {"css_mm", 1e308}}, 422, "\"css_mm\""},
        {{{"time", Day(21)}, {"css_mm", "130"}}, 400, "\"css_mm\" is required"},
        {{{"time", "yesterday"}, {"css_mm", 130}}, 400, "\"time\" 'yesterday'"},
        {{{"time", Day(21)}, {"css_mm", 130}, {"by", "me"}}, 400, "unknown field \"by\""},
        {{{"time", Day(21)}, {"css_mm", 130}, {"note", std::string(1001, 'x')}}, 400, "\"note\" is longer"},
    };
    for (const Case& c : cases) {
      auto [code, body] = post(a, c.body);
      LONGS_EQUAL_TEXT(c.status, code, body.dump().c_str());
      STRCMP_CONTAINS(c.names, body["error"].get<std::string>().c_str());
    }
    auto [read_only, refused] = post(a, {{"time", Day(21)}, {"css_mm", 130}}, kReadToken);
    LONGS_EQUAL(403, read_only);
    auto list = a.Client(kReadToken).Get(a.Base() + "/setting/checks");
    CHECK(list);
    LONGS_EQUAL(2, json::parse(list->body)["checks"].size());
  }
  {
    Api a(db);  // a restart: the checks are read back and the CSS counts from the latest again
    a.LoadAll();
    auto list = a.Client(kReadToken).Get(a.Base() + "/setting/checks");
    CHECK(list);
    const json checks = json::parse(list->body)["checks"];
    LONGS_EQUAL(2, checks.size());
    CHECK(checks[1] == made);
    DOUBLES_EQUAL(131.5, a.Wear()["setting"]["checked"]["css_mm"].get<double>(), 1e-9);
  }
}

// A check's opening follows what it measured: a check posted before the readings of its time
// arrive is not known (and not 0: the liner had run 20 days), and is estimated at the next start;
// a reline dated before it makes it the new liner's, a void of that reline the old liner's again.
TEST(Campaigns, ASettingChecksOpeningFollowsTheLinerItMeasured) {
  lw::test::TempDirectory keep{"lw-setting-liner"};
  const std::string db = keep.File("db.sqlite");
  const std::string at = Day(15);  // the readings reach past it
  const auto listed = [](Api& a) {
    auto res = a.Client(kReadToken).Get(a.Base() + "/setting/checks");
    CHECK(res);
    LONGS_EQUAL_TEXT(200, res->status, res->body.c_str());
    const json checks = json::parse(res->body)["checks"];
    LONGS_EQUAL(2, checks.size());
    return checks[1];
  };
  // The earlier check (day 5, the first liner's in every campaign below).
  const auto early = [](Api& a) {
    auto res = a.Client(kReadToken).Get(a.Base() + "/setting/checks");
    CHECK(res);
    return json::parse(res->body)["checks"][0];
  };
  // The opening GET .../wear?at= gives at the check's time, and the one the live wear counts from.
  const auto expect_as_wear_then = [&](Api& a) {
    auto then = a.Client(kReadToken).Get(a.Base() + "/wear?faces=false&at=" + at);
    CHECK(then);
    const json setting_then = json::parse(then->body)["setting"];
    const json check = listed(a);
    if (setting_then["opening_mm"].is_number()) {
      CHECK_TEXT(check["opening_mm"].is_number(), check.dump().c_str());
      DOUBLES_EQUAL(setting_then["opening_mm"].get<double>(), check["opening_mm"].get<double>(), 0.011);
      CHECK(check["opening_supported"] == setting_then["supported"]);
    } else {
      CHECK_TEXT(check["opening_mm"].is_null(), check.dump().c_str());
    }
    const json live = a.Wear()["setting"]["checked"];
    CHECK_TEXT(live.is_object(), a.Wear()["setting"].dump().c_str());
    CHECK_TEXT(live["opening_mm"] == check["opening_mm"], (live.dump() + " vs " + check.dump()).c_str());
    CHECK_TRUE(check["counts"].get<bool>());
    return check;
  };
  json first_liner;
  {
    Api a(db);
    auto res = a.Client().Post(a.Base() + "/setting/checks", json({{"time", at}, {"css_mm", 131}}).dump(), "application/json");
    CHECK(res);
    LONGS_EQUAL_TEXT(201, res->status, res->body.c_str());
    const json made = json::parse(res->body);
    CHECK_TEXT(made["opening_mm"].is_null(), made.dump().c_str());  // no reading up to day 15: not known
    CHECK_FALSE(made["opening_supported"].get<bool>());
    a.LoadAll();  // the readings of the 20 days arrive late
    auto five =
        a.Client().Post(a.Base() + "/setting/checks", json({{"time", Day(5)}, {"css_mm", 128}}).dump(), "application/json");
    CHECK(five);
    LONGS_EQUAL_TEXT(201, five->status, five->body.c_str());
    CHECK(listed(a)["opening_mm"].is_null());  // not moved by the readings' commit itself
    // The wear worker's step before it computes the wear: estimated from the readings now stored,
    // and not tried again while nothing is unknown.
    CHECK(a.parts.campaigns->EstimateUnknownSettings(Folder().id()) == CampaignService::UnknownSettings::kEstimated);
    first_liner = expect_as_wear_then(a);
    {
      Store stored(db);  // kept in the database, not only in the live wear
      bool found = false;
      for (const SettingCheckRecord& c : stored.SettingChecks(Folder().id()))
        if (lw::core::FormatIsoSeconds(c.time_s) == at) found = c.opening_mm.has_value();
      CHECK_TRUE(found);
    }
    CHECK(a.parts.campaigns->EstimateUnknownSettings(Folder().id()) == CampaignService::UnknownSettings::kNone);
  }
  json day5;
  {
    Api a(db);  // the next start reads them back as estimated
    CHECK(expect_as_wear_then(a) == first_liner);
    day5 = early(a);
    CHECK_TEXT(day5["opening_mm"].is_number(), day5.dump().c_str());
    CHECK_TEXT(first_liner["opening_mm"].is_number(), first_liner.dump().c_str());
    CHECK_TRUE(first_liner["opening_supported"].get<bool>());
    // A reline dated before the check: the check measured the new liner.
    const double fresh = Folder().bundle.crusher.thickness_new_mm + 15;
    auto [status, made] = a.Reline({{"time", Day(12)}, {"thickness_new_mm", fresh}});
    LONGS_EQUAL_TEXT(201, status, made.dump().c_str());
    const json new_liner = expect_as_wear_then(a);
    // The day-5 check measured the liner before the reline: kept as it was, and no longer counted.
    const json before_reline = early(a);
    CHECK(before_reline["opening_mm"] == day5["opening_mm"]);
    CHECK_FALSE(before_reline["counts"].get<bool>());
    CHECK_TEXT(new_liner["opening_mm"] != first_liner["opening_mm"], (new_liner.dump() + " vs " + first_liner.dump()).c_str());
    // The reline voided: the check is the first liner's again.
    auto res = a.Client().Post(a.Base() + "/relines/" + Day(12) + "/void", json({{"reason", "test"}}).dump(), "application/json");
    CHECK(res);
    LONGS_EQUAL_TEXT(200, res->status, res->body.c_str());
    DOUBLES_EQUAL(first_liner["opening_mm"].get<double>(), expect_as_wear_then(a)["opening_mm"].get<double>(), 0.011);
    CHECK_TRUE(early(a)["counts"].get<bool>());
  }
  {
    Api a(db);  // and so after a restart
    DOUBLES_EQUAL(first_liner["opening_mm"].get<double>(), expect_as_wear_then(a)["opening_mm"].get<double>(), 0.011);
  }
}

// With no reading up to a check, the liner has not opened only within a day of its installation:
// a check at installed_at and one a day later count 0, one a second after that is not known (the
// alarm holds) and is estimated at the next start from the readings stored by then.
TEST(Campaigns, ACheckWithNoReadingBeforeItIsZeroOnlyOnTheLinersFirstDay) {
  lw::test::TempDirectory keep{"lw-setting-edge"};
  const std::string db = keep.File("db.sqlite");
  const auto post = [](Api& a, const std::string& time) {
    auto res = a.Client().Post(a.Base() + "/setting/checks", json({{"time", time}, {"css_mm", 130}}).dump(), "application/json");
    CHECK(res);
    LONGS_EQUAL_TEXT(201, res->status, res->body.c_str());
    return json::parse(res->body);
  };
  const std::string after_a_day = lw::core::FormatIsoTime(*lw::core::ParseIsoTime(Day(1)) + std::chrono::seconds(1));
  {
    Api a(db);
    const json at_install = post(a, Day(0));
    DOUBLES_EQUAL(0.0, at_install["opening_mm"].get<double>(), 1e-9);
    CHECK_TRUE(at_install["opening_supported"].get<bool>());
    DOUBLES_EQUAL(0.0, post(a, Day(1))["opening_mm"].get<double>(), 1e-9);
    const json late = post(a, after_a_day);
    CHECK_TEXT(late["opening_mm"].is_null(), late.dump().c_str());
    a.LoadAll();
  }
  {
    Api a(db);
    auto res = a.Client(kReadToken).Get(a.Base() + "/setting/checks");
    CHECK(res);
    const json checks = json::parse(res->body)["checks"];
    LONGS_EQUAL(3, checks.size());
    CHECK_TEXT(checks[2]["opening_mm"].is_number(), checks[2].dump().c_str());
    auto then = a.Client(kReadToken).Get(a.Base() + "/wear?faces=false&at=" + after_a_day);
    CHECK(then);
    const json setting_then = json::parse(then->body)["setting"];
    CHECK_TEXT(setting_then["opening_mm"].is_number(), setting_then.dump().c_str());
    DOUBLES_EQUAL(setting_then["opening_mm"].get<double>(), checks[2]["opening_mm"].get<double>(), 0.011);
    DOUBLES_EQUAL(0.0, checks[0]["opening_mm"].get<double>(), 1e-9);  // a known opening is kept
  }
}

// A void's body, like a reline's, is refused before it is parsed when it nests deeper than any
// body of the route can (its parsed value would be copied or printed one stack frame per level).
TEST(Campaigns, AVoidBodyNestedTooDeeplyIsRefusedBeforeItIsParsed) {
  const std::string deep = std::string(30'000, '[') + std::string(30'000, ']');
  for (const std::string& body : {R"({"reason": )" + deep + "}", deep}) {
    try {
      ParseVoidBody(body);
      FAIL("a body nested 30,000 deep was taken");
    } catch (const RelineError& e) {
      LONGS_EQUAL(400, e.status());
      STRCMP_EQUAL("body is nested too deeply", e.what());
    }
  }
  STRCMP_EQUAL("x", ParseVoidBody(R"({"reason": "x"})").c_str());
}
