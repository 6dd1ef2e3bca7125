// Relines through the real HTTP server on loopback and a real SQLite file (docs/server.md).
#include <chrono>
#include <string>

#include "core/time.hpp"
#include "server/http_api.hpp"
#include "unit/server/server_fixture.hpp"

// After Eigen: <resolv.h> (via httplib) defines the macro _res, a parameter name inside Eigen.
#include <httplib.h>

#include <CppUTest/TestHarness.h>  // last: its leak-detection macros clash with std headers

using namespace lw::server;
using nlohmann::json;

namespace {
lw::test::CrusherFolder& Folder() {
  static lw::test::CrusherFolder f(20, 11);
  return f;
}
const char* kReadToken = lw::test::ServerParts::kReadToken;
const char* kWriteToken = lw::test::ServerParts::kWriteToken;

/// A real HttpApi on 127.0.0.1 over the database `db` (empty: a fresh one).
struct Api {
  lw::test::ServerParts parts;
  std::unique_ptr<HttpApi> api;
  int port = 0;
  explicit Api(const std::string& db = "") : parts(Folder().crushers, true, "", db) {
    api = std::make_unique<HttpApi>(parts.ctx);
    port = api->Bind("127.0.0.1", 0);
    api->Start();
  }
  ~Api() { api->Stop(); }
  httplib::Client Client(const char* token = kWriteToken) {
    httplib::Client c("127.0.0.1", port);
    c.set_read_timeout(60, 0);
    c.set_bearer_token_auth(token);
    return c;
  }
  std::string Base() const { return "/api/v1/crushers/" + Folder().id(); }
  void LoadAll() {
    json body = {{"readings", json::array()}};
    for (const auto& m : lw::test::Messages(Folder().bundle)) body["readings"].push_back(json::parse(m.payload));
    auto res = Client().Post(Base() + "/readings", body.dump(), "application/json");
    CHECK(res);
    LONGS_EQUAL(200, res->status);
  }
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
