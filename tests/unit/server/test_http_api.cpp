#include <filesystem>
#include <fstream>
#include <thread>

#include "core/wear_map.hpp"
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
const char* kReadToken = "reader-secret";
const char* kWriteToken = "writer-secret";

/// A server's worth of parts around a real HttpApi on 127.0.0.1 (any free port).
struct Api {
  lw::test::TempDirectory dir{"lw-http"};
  std::unique_ptr<Registry> registry;
  Store write{dir.File("db.sqlite")};
  Store read{dir.File("db.sqlite")};
  std::mutex read_mutex;
  std::unique_ptr<Ingestor> ingestor;
  std::unique_ptr<WearService> wear;
  EventBus events;
  std::unique_ptr<DiagnosisRunner> diagnosis;
  TokenStore tokens;
  std::unique_ptr<HttpApi> api;
  int port = 0;

  explicit Api(bool with_tokens, const std::string& web_dir = "") {
    std::vector<std::string> errors;
    registry = Registry::Load(Folder().crushers, &errors);
    ingestor = std::make_unique<Ingestor>(write, *registry, [] { return int64_t{4'000'000'000}; });
    wear = std::make_unique<WearService>(*registry, read, read_mutex);
    diagnosis = std::make_unique<DiagnosisRunner>(*registry, read, read_mutex);
    if (with_tokens) {
      tokens.Add({"reader", lw::core::Sha256Hex(kReadToken), true, false});
      tokens.Add({"writer", lw::core::Sha256Hex(kWriteToken), true, true});
    }
    ApiContext ctx;
    ctx.registry = registry.get();
    ctx.read = &read;
    ctx.read_mutex = &read_mutex;
    ctx.wear = wear.get();
    ctx.ingestor = ingestor.get();
    ctx.events = &events;
    ctx.diagnosis = diagnosis.get();
    ctx.tokens = &tokens;
    ctx.web_dir = web_dir;
    ctx.after_ingest = [this](const IngestResult& r) {
      for (const auto& s : r.new_readings) {
        wear->MarkChanged(s.crusher);
        events.Publish(s.crusher, "reading", json{{"sensor", s.sensor}, {"seq", s.seq}}.dump());
      }
    };
    api = std::make_unique<HttpApi>(ctx);
    port = api->Bind("127.0.0.1", 0);
    api->Start();
  }
  ~Api() { api->Stop(); }

  httplib::Client Client(const char* token = nullptr) {
    httplib::Client c("127.0.0.1", port);
    c.set_read_timeout(60, 0);
    if (token) c.set_bearer_token_auth(token);
    return c;
  }
  std::string Base() const { return "/api/v1/crushers/" + Folder().id(); }

  void LoadAll(const char* token = nullptr) {
    json body = {{"readings", json::array()}};
    for (const auto& m : lw::test::Messages(Folder().bundle)) body["readings"].push_back(json::parse(m.payload));
    auto res = Client(token).Post(Base() + "/readings", body.dump(), "application/json");
    CHECK(res);
    LONGS_EQUAL(200, res->status);
  }
};

json Get(httplib::Client& c, const std::string& path, int expect = 200) {
  auto res = c.Get(path);
  CHECK_TEXT(res, path.c_str());
  LONGS_EQUAL_TEXT(expect, res->status, (path + ": " + res->body).c_str());
  return json::parse(res->body);
}
}  // namespace

TEST_GROUP(HttpApi){};

TEST(HttpApi, ReadingsPagesMatchTheStoredDataExactly) {
  Api a(false);
  a.LoadAll();
  auto c = a.Client();
  const auto& b = Folder().bundle;
  std::vector<std::pair<std::string, double>> expected;  // (time, thickness) of sensor 1003
  for (const auto& r : b.readings) {
    if (r.sensor_id == "1003") expected.emplace_back(lw::core::FormatIsoTime(r.time), r.thickness_mm);
  }
  std::vector<std::pair<std::string, double>> got;
  std::string cursor;
  int pages = 0;
  do {
    const json j = Get(c, a.Base() + "/sensors/1003/readings?limit=37" + (cursor.empty() ? "" : "&cursor=" + cursor));
    for (const auto& r : j["readings"]) got.emplace_back(r["time"], r["thickness_mm"]);
    cursor = j["next_cursor"].is_null() ? "" : j["next_cursor"].get<std::string>();
    ++pages;
  } while (!cursor.empty() && pages < 1000);
  LONGS_EQUAL(expected.size(), got.size());
  CHECK(expected == got);
  // from/to are inclusive bounds on the sample time.
  const json window = Get(c, a.Base() + "/sensors/1003/readings?from=" + expected[10].first + "&to=" + expected[19].first);
  LONGS_EQUAL(10, window["readings"].size());
  CHECK(window["next_cursor"].is_null());
  // Sensors: latest of each and counts.
  const json sensors = Get(c, a.Base() + "/sensors");
  for (const auto& s : sensors["sensors"]) {
    if (s["id"] == "1003") {
      LONGS_EQUAL(expected.size(), s["reading_count"].get<long>());
      DOUBLES_EQUAL(expected.back().second, s["latest"]["thickness_mm"].get<double>(), 0);
    }
  }
}

TEST(HttpApi, WearForecastMeshAndVtkDescribeTheSameLiner) {
  Api a(false);
  auto c = a.Client();
  const json none = Get(c, a.Base() + "/wear", 404);
  CHECK(none["error"].get<std::string>().find("no readings") != std::string::npos);
  a.LoadAll();
  const json wear = Get(c, a.Base() + "/wear");
  const json mesh = Get(c, a.Base() + "/mesh");
  const size_t faces = Folder().bundle.map.face_count();
  LONGS_EQUAL(faces, wear["remaining_mm"].size());
  LONGS_EQUAL(faces * 3, mesh["faces"].size());
  double min = 1e9;
  for (const auto& v : wear["remaining_mm"]) min = std::min(min, v.get<double>());
  DOUBLES_EQUAL(wear["min_thickness_mm"].get<double>(), min, 1e-3);
  LONGS_EQUAL(3, wear["rows"].size());
  const json forecast = Get(c, a.Base() + "/forecast");
  LONGS_EQUAL(3, forecast["rows"].size());
  CHECK(forecast["map_sha256"] == wear["map_sha256"]);
  CHECK(forecast["readings_used"] == wear["readings_used"]);
  for (const auto& s : forecast["sensors"]) {
    CHECK_TRUE(s["ok"].get<bool>());
    CHECK(s["rate_mm_per_day"].get<double>() > 0);
    if (!s["reach_earliest"].is_null() && !s["reach_date"].is_null()) {
      CHECK(s["reach_earliest"].get<std::string>() <= s["reach_date"].get<std::string>());
    }
  }
  auto vtk = c.Get(a.Base() + "/wear?format=vtk");
  CHECK(vtk);
  LONGS_EQUAL(200, vtk->status);
  CHECK(vtk->body.rfind("# vtk DataFile Version", 0) == 0);
  CHECK(vtk->body.find("remaining_mm") != std::string::npos);
  Get(c, a.Base() + "/wear?format=png", 400);
  const json list = Get(c, "/api/v1/crushers");
  DOUBLES_EQUAL(wear["min_thickness_mm"].get<double>(), list["crushers"][0]["min_thickness_mm"].get<double>(), 1e-3);
}

TEST(HttpApi, TokensAreRequiredAndScopesEnforced) {
  Api a(true);
  auto anon = a.Client();
  auto reader = a.Client(kReadToken);
  auto writer = a.Client(kWriteToken);
  auto wrong = a.Client("guess");
  Get(anon, "/healthz");  // liveness needs no token
  Get(anon, "/api/v1/crushers", 401);
  Get(wrong, "/api/v1/crushers", 401);
  Get(reader, "/api/v1/crushers");
  const std::string body = R"({"readings":[]})";
  auto res = reader.Post(a.Base() + "/readings", body, "application/json");
  LONGS_EQUAL(403, res->status);
  CHECK(json::parse(res->body)["error"].get<std::string>().find("write") != std::string::npos);
  res = writer.Post(a.Base() + "/readings", body, "application/json");
  LONGS_EQUAL(200, res->status);
  const json me = Get(reader, "/api/v1/whoami");
  STRCMP_EQUAL("reader", me["name"].get<std::string>().c_str());
  CHECK(me["scopes"] == json::array({"read"}));
  CHECK(Get(writer, "/api/v1/whoami")["scopes"] == json::array({"read", "write"}));
  // EventSource cannot set headers: the token may come as a query parameter.
  auto q = anon.Get("/api/v1/openapi.json?access_token=" + std::string(kReadToken));
  LONGS_EQUAL(200, q->status);
}

TEST(HttpApi, BadRequestsGetJsonErrorsAndNothingStoredIsLost) {
  Api a(false);
  a.LoadAll();
  auto c = a.Client();
  const long before = Get(c, a.Base())["counters"]["readings_stored"].get<long>();
  Get(c, "/api/v1/crushers/nope", 404);
  Get(c, a.Base() + "/sensors/9999/readings", 404);
  Get(c, a.Base() + "/sensors/1001/readings?limit=0", 400);
  Get(c, a.Base() + "/sensors/1001/readings?limit=abc", 400);
  Get(c, a.Base() + "/sensors/1001/readings?from=2026-13-01", 400);
  Get(c, a.Base() + "/sensors/1001/readings?cursor=bogus", 400);
  Get(c, "/api/v1/no/such/thing", 404);
  auto res = c.Post(a.Base() + "/readings", "{oops", "application/json");
  LONGS_EQUAL(400, res->status);
  res = c.Post(a.Base() + "/readings", R"({"readings":[{"sensor":"1001","seq":1,"time":"2099-01-01T00:00:00Z"}]})", "application/json");
  LONGS_EQUAL(422, res->status);
  LONGS_EQUAL(before, Get(c, a.Base())["counters"]["readings_stored"].get<long>());
  const json rejected = Get(c, "/api/v1/rejected");
  LONGS_EQUAL(1, rejected["total"].get<long>());
  const json doc = Get(c, "/api/v1/openapi.json");
  STRCMP_EQUAL("3.0.3", doc["openapi"].get<std::string>().c_str());
  CHECK(doc["paths"].contains("/api/v1/crushers/{crusher}/forecast"));
}

namespace {
/// Opens /events (optionally resuming from `last_event_id`), posts one reading once the stream is
/// open, and returns what the stream carried until a `reading` event arrived (or 10 s passed).
std::string StreamOneReading(Api& a, const std::string& last_event_id = "") {
  std::string received;
  std::atomic<bool> got{false};
  std::thread listener([&] {
    auto c = a.Client();
    httplib::Headers headers;
    if (!last_event_id.empty()) headers.emplace("Last-Event-ID", last_event_id);
    c.Get(a.Base() + "/events", headers, [&](const char* data, size_t n) {
      received.append(data, n);
      if (received.find("event: reading") != std::string::npos) {
        got = true;
        return false;
      }
      return true;
    });
  });
  // Wait until the stream is open, then post one reading.
  for (int i = 0; i < 100 && received.empty(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  auto c = a.Client();
  const auto msg = lw::test::Messages(Folder().bundle).front();
  c.Post(a.Base() + "/readings", json{{"readings", {json::parse(msg.payload)}}}.dump(), "application/json");
  for (int i = 0; i < 200 && !got; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  a.events.Close();
  listener.join();
  return received;
}
}  // namespace

TEST(HttpApi, EventsStreamNewReadings) {
  Api a(false);
  const std::string received = StreamOneReading(a);
  CHECK(received.find("event: reading") != std::string::npos);
  CHECK(received.find("\"seq\":1") != std::string::npos);
}

TEST(HttpApi, AnEventIdFromBeforeARestartDoesNotSilenceTheStream) {
  Api a(false);  // a fresh server: its event ids start at 1
  const std::string received = StreamOneReading(a, "12000");
  CHECK(received.find("event: reading") != std::string::npos);
}

TEST(HttpApi, DiagnosisRunsOnTheStoredReadings) {
  Api a(false);
  a.LoadAll();
  auto c = a.Client();
  STRCMP_EQUAL("none", Get(c, a.Base() + "/diagnosis")["status"].get<std::string>().c_str());
  auto res = c.Post(a.Base() + "/diagnosis", "", "application/json");
  LONGS_EQUAL(202, res->status);
  json j;
  for (int i = 0; i < 600; ++i) {
    j = Get(c, a.Base() + "/diagnosis");
    if (j["status"] != "running") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  STRCMP_EQUAL("done", j["status"].get<std::string>().c_str());
  CHECK(j["result"]["baseline"].contains("rmse_mm"));
  CHECK(j["result"]["mismatch"].contains("detected"));
}

TEST(HttpApi, ServesTheDashboardPageAndAssetsOnly) {
  lw::test::TempDirectory web{"lw-web"};
  std::filesystem::create_directories(web.File("assets"));
  std::filesystem::create_directories(web.File("CMakeFiles"));
  { std::ofstream(web.File("index.html")) << "<!doctype html><title>dash</title>"; }
  { std::ofstream(web.File("assets/app.js")) << "console.log(1)"; }
  { std::ofstream(web.File("CMakeFiles/secret.txt")) << "build paths"; }
  Api a(true, web.path());
  auto c = a.Client();  // no token: the page itself is public, the API is not
  auto res = c.Get("/");
  LONGS_EQUAL(200, res->status);
  CHECK(res->body.find("<title>dash</title>") != std::string::npos);
  res = c.Get("/assets/app.js");
  LONGS_EQUAL(200, res->status);
  STRCMP_EQUAL("console.log(1)", res->body.c_str());
  LONGS_EQUAL(404, c.Get("/CMakeFiles/secret.txt")->status);
  LONGS_EQUAL(401, c.Get("/api/v1/crushers")->status);
}

TEST(HttpApi, HostileRequestsGetErrorsNotACrash) {
  Api a(false);
  auto c = a.Client();
  // A path that is not valid UTF-8 once decoded: the error text must still be sendable.
  auto res = c.Get("/%FF%FE");
  CHECK(res);
  LONGS_EQUAL(404, res->status);
  CHECK(json::parse(res->body).contains("error"));
  // JSON nested far deeper than any reading: refused before it is parsed or re-serialised.
  const std::string deep = "{\"readings\":[" + std::string(100000, '[') + std::string(100000, ']') + "]}";
  res = c.Post(a.Base() + "/readings", deep, "application/json");
  CHECK(res);
  LONGS_EQUAL(400, res->status);
  // A reading with bytes that are not UTF-8 is quarantined, and listing it still works.
  res = c.Post(a.Base() + "/readings", "{\"readings\":[{\"sensor\":\"1001\",\"seq\":1,\"time\":\"\xff\"}]}", "application/json");
  CHECK(res);
  CHECK(res->status == 400 || res->status == 422);
  // The server is still up.
  Get(c, "/healthz");
  Get(c, "/api/v1/rejected");
}
