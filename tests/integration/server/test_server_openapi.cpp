// The real linerwatch-server's answers against its own OpenAPI document (GET /api/v1/openapi.json):
// every operation is called over loopback, successes and the errors a client meets (unknown
// crusher or sensor, bad query, bad body, wrong media type, cross-origin, a Host not served, no
// token, a token without the scope, framing the HTTP guard refuses), and each answer is recorded;
// validate_openapi.py (python3-jsonschema) then checks each status is declared for its operation,
// its media type declared for that status, and its JSON body valid against the declared schema.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdio.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <thread>

#include "core/wear_map.hpp"  // Sha256Hex
#include "support/mosquitto_fixture.hpp"
#include "unit/server/server_fixture.hpp"

#include <httplib.h>  // after Eigen (<resolv.h> defines _res)

#include <CppUTest/TestHarness.h>  // last

using nlohmann::json;

namespace {

struct Server {
  lw::test::ChildProcess process;
  std::string log;
  int port = 0;
  void Start(const std::string& broker, const lw::test::CrusherFolder& folder, std::vector<std::string> extra = {}) {
    port = lw::test::FreeLoopbackPort();
    log = folder.dir.File("server-" + std::to_string(port) + ".log");
    std::vector<std::string> argv = {LW_SERVER_BIN,
                                     "--broker",
                                     broker,
                                     "--db",
                                     folder.dir.File("server-" + std::to_string(port) + ".sqlite"),
                                     "--http",
                                     "127.0.0.1:" + std::to_string(port),
                                     "--crusher-dir",
                                     folder.crushers,
                                     "--web-dir",
                                     ""};
    argv.insert(argv.end(), extra.begin(), extra.end());
    process.Start(argv, log);
    for (int i = 0; i < 1200 && !lw::test::PortAccepts(port); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (!lw::test::PortAccepts(port)) FAIL(("server did not come up: " + lw::test::FileTail(log)).c_str());
  }
};

/// A raw HTTP exchange: what httplib's client would never send (no Content-Length, a huge
/// header); the status, media type and body of the answer.
struct RawAnswer {
  int status = 0;
  std::string content_type;
  std::string body;
};

RawAnswer Raw(int port, const std::string& request) {
  RawAnswer a;
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in dst{};
  dst.sin_family = AF_INET;
  dst.sin_port = htons(static_cast<uint16_t>(port));
  ::inet_pton(AF_INET, "127.0.0.1", &dst.sin_addr);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&dst), sizeof dst) != 0) {
    ::close(fd);
    return a;
  }
  [[maybe_unused]] const ssize_t sent = ::send(fd, request.data(), request.size(), MSG_NOSIGNAL);
  std::string in;
  char buf[4096];
  while (true) {  // until the server closes or 5 s pass without data
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 5000) <= 0) break;
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    in.append(buf, static_cast<size_t>(n));
    const size_t head_end = in.find("\r\n\r\n");
    const size_t length_at = in.find("Content-Length: ");
    if (head_end != std::string::npos && length_at != std::string::npos && length_at < head_end &&
        in.size() >= head_end + 4 + std::stoul(in.substr(length_at + 16)))
      break;
  }
  ::close(fd);
  if (in.rfind("HTTP/1.1 ", 0) != 0) return a;
  a.status = std::atoi(in.c_str() + 9);
  const size_t head_end = in.find("\r\n\r\n");
  const size_t type_at = in.find("Content-Type: ");
  if (type_at != std::string::npos && type_at < head_end)
    a.content_type = in.substr(type_at + 14, in.find("\r\n", type_at) - type_at - 14);
  if (head_end != std::string::npos) a.body = in.substr(head_end + 4);
  return a;
}

/// Every answer the test got, as validate_openapi.py reads them.
struct Recorder {
  json exchanges = json::array();

  /// Records `res` to `method url` (an operation's `path_template`; "" for a request no operation
  /// has) and checks its status is `expected` (0: any).
  void Add(const char* method, const std::string& path_template, const std::string& url, const httplib::Result& res,
           int expected = 200, const json* request = nullptr) {
    CHECK_TEXT(res, (std::string(method) + " " + url + ": no answer").c_str());
    if (!res) return;
    Add(method, path_template, url, {res->status, res->get_header_value("Content-Type"), res->body}, expected, request);
  }
  void Add(const char* method, const std::string& path_template, const std::string& url, const RawAnswer& a, int expected,
           const json* request = nullptr) {
    if (expected) LONGS_EQUAL_TEXT(expected, a.status, (std::string(method) + " " + url + ": " + a.body.substr(0, 300)).c_str());
    json x = {{"method", method},
              {"path", path_template.empty() ? json(nullptr) : json(path_template)},
              {"url", url},
              {"status", a.status},
              {"content_type", a.content_type},
              {"body", a.body}};
    if (request) x["request"] = *request;
    exchanges.push_back(std::move(x));
  }
};

/// Runs validate_openapi.py on the document and the answers; "" when it passes, else what it said.
std::string Validate(const lw::test::TempDirectory& dir, const std::string& openapi, const json& exchanges, std::string* said) {
  const std::string doc_path = dir.File("openapi.json"), exchanges_path = dir.File("exchanges.json");
  std::ofstream(doc_path) << openapi;
  std::ofstream(exchanges_path) << exchanges.dump(1);
  const std::string command =
      std::string(LW_PYTHON3) + " " + LW_OPENAPI_VALIDATOR + " " + doc_path + " " + exchanges_path + " 2>&1";
  FILE* p = ::popen(command.c_str(), "r");
  char buf[1024];
  while (p && ::fgets(buf, sizeof buf, p)) *said += buf;
  const int status = p ? ::pclose(p) : -1;
  return WIFEXITED(status) && WEXITSTATUS(status) == 0 ? std::string() : "validate_openapi.py failed:\n" + *said;
}

const std::string kCrusher = "/api/v1/crushers/{crusher}";

/// The calls, over one server's HTTP (and a second with --tokens), each answer recorded.
class ApiTour {
 public:
  ApiTour(const lw::test::CrusherFolder& folder, const lw::test::MosquittoFixture& broker, int port)
      : folder_(folder), broker_(broker), port_(port), http_("127.0.0.1", port) {
    http_.set_read_timeout(60, 0);
  }
  httplib::Client& http() { return http_; }
  Recorder rec;

  std::string Base() const { return "/api/v1/crushers/" + folder_.id(); }
  /// GET `url` (of the operation `path_template`) until it answers `want` (bounded), recording each answer.
  void GetUntil(const std::string& path_template, const std::string& url, int want) {
    for (int i = 0; i < 600; ++i) {
      const auto res = http_.Get(url);
      rec.Add("get", path_template, url, res, 0);
      if (!res || res->status == want) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    LONGS_EQUAL_TEXT(want, rec.exchanges.back()["status"].get<int>(), url.c_str());
  }
  void PostReadings();
  void Reads();
  void Writes();
  void Refusals();
  void WithTokens();

 private:
  const lw::test::CrusherFolder& folder_;
  const lw::test::MosquittoFixture& broker_;
  int port_;
  httplib::Client http_;
};

/// The readings, posted as a gateway without MQTT would: the first batch's body is checked too.
void ApiTour::PostReadings() {
  const auto messages = lw::test::Messages(folder_.bundle);
  for (size_t from = 0; from < messages.size(); from += 5000) {
    json body = {{"readings", json::array()}};
    for (size_t i = from; i < std::min(messages.size(), from + 5000); ++i)
      body["readings"].push_back(json::parse(messages[i].payload));
    rec.Add("post", kCrusher + "/readings", Base() + "/readings",
            http_.Post(Base() + "/readings", body.dump(), "application/json"), 200, from == 0 ? &body : nullptr);
  }
}

/// Every GET operation, with its success and the errors of its parameters.
void ApiTour::Reads() {
  const std::string base = Base();
  const std::string sensor = folder_.bundle.crusher.sensors.front().id;
  const std::string readings = base + "/sensors/" + sensor + "/readings";
  const std::string readings_t = kCrusher + "/sensors/{sensor}/readings";
  rec.Add("get", "/api/v1/crushers", "/api/v1/crushers", http_.Get("/api/v1/crushers"));
  rec.Add("get", kCrusher, base, http_.Get(base));
  rec.Add("get", kCrusher, "/api/v1/crushers/nope", http_.Get("/api/v1/crushers/nope"), 404);
  rec.Add("get", kCrusher + "/sensors", base + "/sensors", http_.Get(base + "/sensors"));
  const auto page = http_.Get(readings + "?limit=5");
  rec.Add("get", readings_t, readings + "?limit=5", page);
  const std::string cursor = json::parse(page->body)["next_cursor"].get<std::string>();  // more than 5: a string
  rec.Add("get", readings_t, readings + "?limit=5&cursor=" + cursor, http_.Get(readings + "?limit=5&cursor=" + cursor));
  rec.Add("get", readings_t, readings + "?format=csv", http_.Get(readings + "?format=csv"));
  rec.Add("get", readings_t, readings + "?limit=0", http_.Get(readings + "?limit=0"), 400);
  rec.Add("get", readings_t, base + "/sensors/nope/readings", http_.Get(base + "/sensors/nope/readings"), 404);
  rec.Add("get", kCrusher + "/mesh", base + "/mesh", http_.Get(base + "/mesh"));
  for (const char* q : {"", "?faces=false", "?format=vtk", "?format=csv"})
    rec.Add("get", kCrusher + "/wear", base + "/wear" + q, http_.Get(base + "/wear" + q));
  const std::string at =
      lw::core::FormatIsoTime(lw::core::TimePoint(std::chrono::seconds(lw::test::LatestReadingS(folder_.bundle) - 86400)));
  rec.Add("get", kCrusher + "/wear", base + "/wear?at=" + at, http_.Get(base + "/wear?at=" + at));
  rec.Add("get", kCrusher + "/wear", base + "/wear?format=xml", http_.Get(base + "/wear?format=xml"), 400);
  rec.Add("get", kCrusher + "/wear", base + "/wear?at=yesterday", http_.Get(base + "/wear?at=yesterday"), 400);
  for (const char* q : {"", "?format=csv"})
    rec.Add("get", kCrusher + "/forecast", base + "/forecast" + q, http_.Get(base + "/forecast" + q));
  rec.Add("get", kCrusher + "/forecast", base + "/forecast?format=vtk", http_.Get(base + "/forecast?format=vtk"), 400);
  rec.Add("get", kCrusher + "/campaigns", base + "/campaigns", http_.Get(base + "/campaigns"));
  rec.Add("get", kCrusher + "/alarms", base + "/alarms", http_.Get(base + "/alarms"));
  rec.Add("get", kCrusher + "/alarms", base + "/alarms?state=bogus", http_.Get(base + "/alarms?state=bogus"), 400);
  rec.Add("get", kCrusher + "/alarms/rules", base + "/alarms/rules", http_.Get(base + "/alarms/rules"));
  rec.Add("get", kCrusher + "/plan", base + "/plan?sensors=4", http_.Get(base + "/plan?sensors=4"));
  rec.Add("get", kCrusher + "/plan", base + "/plan", http_.Get(base + "/plan"), 400);
  rec.Add("get", "/api/v1/rejected", "/api/v1/rejected", http_.Get("/api/v1/rejected"));
  rec.Add("get", "/api/v1/rejected", "/api/v1/rejected?limit=0", http_.Get("/api/v1/rejected?limit=0"), 400);
  rec.Add("get", "/api/v1/whoami", "/api/v1/whoami", http_.Get("/api/v1/whoami"));
  rec.Add("get", "/metrics", "/metrics", http_.Get("/metrics"));
  // The event stream: its head and first chunk (the preamble), then the client leaves.
  RawAnswer events;
  http_.Get(
      base + "/events", httplib::Headers{},
      [&](const httplib::Response& r) {
        events.status = r.status;
        events.content_type = r.get_header_value("Content-Type");
        return true;
      },
      [&](const char* data, size_t size) {
        events.body.append(data, size);
        return false;
      });
  rec.Add("get", kCrusher + "/events", base + "/events", events, 200);
  CHECK_TEXT(events.body.find("retry: 3000") != std::string::npos, events.body.c_str());
}

/// Every POST operation: a valid body (recorded with the answer, so that it is checked against the
/// requestBody schema) and the bodies each refuses.
void ApiTour::Writes() {
  const std::string base = Base();
  rec.Add("post", kCrusher + "/diagnosis", base + "/diagnosis", http_.Post(base + "/diagnosis", "{}", "application/json"), 202);
  for (int i = 0; i < 1200; ++i) {  // until the diagnosis is no longer running
    const auto res = http_.Get(base + "/diagnosis");
    rec.Add("get", kCrusher + "/diagnosis", base + "/diagnosis", res);
    if (!res || json::parse(res->body)["status"] != "running") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  // Done, with its result: the result's schema is checked on a real diagnosis, not only on null.
  const json diagnosis = json::parse(rec.exchanges.back()["body"].get<std::string>());
  STRCMP_EQUAL_TEXT("done", diagnosis["status"].get<std::string>().c_str(), diagnosis.dump().substr(0, 300).c_str());
  CHECK(diagnosis["result"].is_object());
  const json bad_body = {
      {"readings", {{{"sensor", folder_.bundle.crusher.sensors.front().id}, {"seq", 1}, {"time", "not a time"}}}}};
  rec.Add("post", kCrusher + "/readings", base + "/readings", http_.Post(base + "/readings", bad_body.dump(), "application/json"),
          422);
  rec.Add("post", kCrusher + "/readings", base + "/readings", http_.Post(base + "/readings", "{not json", "application/json"),
          400);
  rec.Add("post", kCrusher + "/readings", base + "/readings", http_.Post(base + "/readings", "{}", "text/plain"), 415);
  rec.Add("post", kCrusher + "/readings", base + "/readings",
          http_.Post(base + "/readings", httplib::Headers{{"Origin", "http://evil.example"}}, "{}", "application/json"), 403);
  const json rules = {{"battery_low", {{"below_mv", 3200}}}};
  rec.Add("post", kCrusher + "/alarms/rules", base + "/alarms/rules",
          http_.Post(base + "/alarms/rules", rules.dump(), "application/json"), 200, &rules);
  rec.Add("post", kCrusher + "/alarms/rules", base + "/alarms/rules",
          http_.Post(base + "/alarms/rules", R"({"no_such_rule":{}})", "application/json"), 400);
  // An alarm to acknowledge: the readings are days old, so the sensors are silent (docs/alarms.md).
  GetUntil(kCrusher + "/alarms", base + "/alarms?state=active&limit=1", 200);
  for (int i = 0; i < 600 && json::parse(rec.exchanges.back()["body"].get<std::string>())["alarms"].empty(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    GetUntil(kCrusher + "/alarms", base + "/alarms?state=active&limit=1", 200);
  }
  const json active = json::parse(rec.exchanges.back()["body"].get<std::string>())["alarms"];
  CHECK_TEXT(!active.empty(), "no active alarm to acknowledge");
  const std::string ack_t = kCrusher + "/alarms/{id}/ack";
  if (!active.empty()) {
    const std::string ack = base + "/alarms/" + std::to_string(active[0]["id"].get<int64_t>()) + "/ack";
    rec.Add("post", ack_t, ack, http_.Post(ack, "{}", "application/json"));
  }
  rec.Add("post", ack_t, base + "/alarms/999999/ack", http_.Post(base + "/alarms/999999/ack", "{}", "application/json"), 404);
  // Last: a reline starts a new liner (the wear then has no readings of it).
  const int64_t reline_s = lw::test::LatestReadingS(folder_.bundle) + 3600;
  const json reline = {{"time", lw::core::FormatIsoTime(lw::core::TimePoint(std::chrono::seconds(reline_s)))},
                       {"thickness_new_mm", folder_.bundle.crusher.thickness_new_mm}};
  const std::string relines = base + "/relines";
  rec.Add("post", kCrusher + "/relines", relines, http_.Post(relines, reline.dump(), "application/json"), 201, &reline);
  rec.Add("post", kCrusher + "/relines", relines, http_.Post(relines, reline.dump(), "application/json"), 200, &reline);
  json differs = reline;
  differs["thickness_new_mm"] = folder_.bundle.crusher.thickness_new_mm - 1;
  rec.Add("post", kCrusher + "/relines", relines, http_.Post(relines, differs.dump(), "application/json"), 409);
  rec.Add("post", kCrusher + "/relines", relines, http_.Post(relines, "{}", "application/json"), 400);
  rec.Add("get", kCrusher + "/campaigns", base + "/campaigns", http_.Get(base + "/campaigns"));
  // Voiding it (a reline posted by mistake): 200 with the voided campaign, again 200 unchanged;
  // the first campaign no reline started (409), a time with no reline (404), a malformed one (400).
  const std::string void_t = kCrusher + "/relines/{time}/void";
  const std::string voids = relines + "/" + reline["time"].get<std::string>() + "/void";
  const json reason = {{"reason", "posted by mistake"}};
  rec.Add("post", void_t, voids, http_.Post(voids, reason.dump(), "application/json"), 200, &reason);
  rec.Add("post", void_t, voids, http_.Post(voids, "", "application/json"), 200);
  const std::string first = relines + "/" + lw::core::FormatIsoTime(folder_.bundle.crusher.installed_at) + "/void";
  rec.Add("post", void_t, first, http_.Post(first, "{}", "application/json"), 409);
  const std::string none = relines + "/2001-01-01T00:00:00Z/void";
  rec.Add("post", void_t, none, http_.Post(none, "{}", "application/json"), 404);
  rec.Add("post", void_t, relines + "/yesterday/void", http_.Post(relines + "/yesterday/void", "{}", "application/json"), 400);
  rec.Add("get", kCrusher + "/campaigns", base + "/campaigns", http_.Get(base + "/campaigns"));
}

/// What the HTTP layer refuses before any handler: requests no operation has, a Host not served,
/// framing the guard refuses.
void ApiTour::Refusals() {
  const std::string base = Base();
  rec.Add("get", "", "/no/such/thing", http_.Get("/no/such/thing"), 404);
  rec.Add("delete", "", "/api/v1/crushers", http_.Delete("/api/v1/crushers"), 405);
  rec.Add("get", "/api/v1/crushers", "/api/v1/crushers (Host: evil.example)",
          http_.Get("/api/v1/crushers", httplib::Headers{{"Host", "evil.example"}}), 421);
  const int port = port_;
  const std::string host = "Host: 127.0.0.1:" + std::to_string(port) + "\r\n";
  rec.Add("post", kCrusher + "/readings", base + "/readings (no Content-Length)",
          Raw(port, "POST " + base + "/readings HTTP/1.1\r\n" + host + "Content-Type: application/json\r\n\r\n"), 411);
  rec.Add("post", kCrusher + "/readings", base + "/readings (Content-Length 1e12)",
          Raw(port, "POST " + base + "/readings HTTP/1.1\r\n" + host +
                        "Content-Type: application/json\r\nContent-Length: 1000000000000\r\n\r\n"),
          413);
  rec.Add("get", "/healthz", "/healthz (a 20 kB header)",
          Raw(port, "GET /healthz HTTP/1.1\r\n" + host + "X-Big: " + std::string(20000, 'a') + "\r\n\r\n"), 431);
  rec.Add("get", "/healthz", "/healthz (Transfer-Encoding: gzip)",
          Raw(port, "GET /healthz HTTP/1.1\r\n" + host + "Transfer-Encoding: gzip\r\n\r\n"), 501);
  rec.Add("get", "/healthz", "/healthz?x=<20 kB>",
          Raw(port, "GET /healthz?x=" + std::string(20000, 'a') + " HTTP/1.1\r\n" + host + "\r\n"), 414);
  rec.Add("get", "/healthz", "/healthz (a malformed header line)",
          Raw(port, "GET /healthz HTTP/1.1\r\n" + host + "no colon here\r\n\r\n"), 400);
}

/// A server with --tokens: no token, a token without the write scope, whoami with a token.
void ApiTour::WithTokens() {
  const std::string tokens = folder_.dir.File("tokens.json");
  std::ofstream(tokens)
      << json{{"tokens", {{{"name", "viewer"}, {"sha256", lw::core::Sha256Hex("view-secret")}, {"scopes", {"read"}}}}}}.dump();
  Server guarded;
  guarded.Start(broker_.uri(), folder_, {"--tokens", tokens, "--client-id", "linerwatch-server-tokens"});
  httplib::Client http("127.0.0.1", guarded.port);
  const httplib::Headers viewer = {{"Authorization", "Bearer view-secret"}};
  rec.Add("get", "/api/v1/crushers", "/api/v1/crushers (no token)", http.Get("/api/v1/crushers"), 401);
  rec.Add("get", "/metrics", "/metrics (no token)", http.Get("/metrics"), 401);
  rec.Add("get", "/api/v1/whoami", "/api/v1/whoami (viewer)", http.Get("/api/v1/whoami", viewer));
  rec.Add("post", kCrusher + "/readings", Base() + "/readings (viewer)",
          http.Post(Base() + "/readings", viewer, R"({"readings":[]})", "application/json"), 403);
  rec.Add("get", "/healthz", "/healthz (no token)", http.Get("/healthz"));
}

}  // namespace

TEST_GROUP(ServerOpenApiLive) {
  lw::test::MosquittoFixture broker;
  lw::test::CrusherFolder folder{10, 5};
  Server server;
  void setup() override {
    broker.Start();
  }
};

TEST(ServerOpenApiLive, EveryAnswerOfEveryOperationMatchesTheDocument) {
  server.Start(broker.uri(), folder);
  ApiTour tour(folder, broker, server.port);
  const std::string base = tour.Base();
  tour.GetUntil("/healthz", "/healthz", 200);
  tour.rec.Add("get", kCrusher + "/diagnosis", base + "/diagnosis", tour.http().Get(base + "/diagnosis"));  // none yet
  tour.PostReadings();
  tour.GetUntil(kCrusher + "/wear", base + "/wear", 200);  // once the wear worker has computed it
  tour.Reads();
  tour.Writes();
  tour.Refusals();
  tour.WithTokens();
  const auto doc = tour.http().Get("/api/v1/openapi.json");
  tour.rec.Add("get", "/api/v1/openapi.json", "/api/v1/openapi.json", doc);
  std::string said;
  const std::string problem = Validate(folder.dir, doc->body, tour.rec.exchanges, &said);
  CHECK_TEXT(problem.empty(), problem.c_str());
  UT_PRINT(said.c_str());  // the (operation, status) pairs checked, in ctest --verbose
}
