// The real linerwatch-server's GET /metrics, scraped over loopback as Prometheus would: the text
// passes Prometheus' own parser and linter (promtool check metrics), the readings counter moves
// when readings are posted, requests are counted by route and status, and with --tokens the
// scrape needs a token with the read scope.
#include <chrono>
#include <fstream>
#include <thread>

#include "core/wear_map.hpp"  // Sha256Hex
#include "support/grafana.hpp"
#include "support/mosquitto_fixture.hpp"
#include "support/promtool.hpp"
#include "unit/server/server_fixture.hpp"

#include <httplib.h>  // after Eigen (<resolv.h> defines _res)

#include <CppUTest/TestHarness.h>  // last

using nlohmann::json;

namespace {

/// The value of the sample `series` (name with its labels, as written) in `text`; -1 when absent.
double ValueOf(const std::string& text, const std::string& series) {
  const size_t at = text.find("\n" + series + " ");
  if (at == std::string::npos) return -1;
  return std::stod(text.substr(at + series.size() + 2));
}

struct Server {
  lw::test::ChildProcess process;
  std::string log;
  int port = 0;
  void Start(const std::string& broker, const lw::test::CrusherFolder& folder, std::vector<std::string> extra = {}) {
    port = lw::test::FreeLoopbackPort();
    log = folder.dir.File("server.log");
    std::vector<std::string> argv = {LW_SERVER_BIN,
                                     "--broker",
                                     broker,
                                     "--db",
                                     folder.dir.File("server.sqlite"),
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

std::string Scrape(httplib::Client& http, const httplib::Headers& headers = {}) {
  const auto res = http.Get("/metrics", headers);
  CHECK(res);
  LONGS_EQUAL_TEXT(200, res->status, res->body.c_str());
  STRCMP_EQUAL("text/plain; version=0.0.4; charset=utf-8", res->get_header_value("Content-Type").c_str());
  const std::string problem = lw::test::PromtoolCheck(res->body);
  CHECK_TEXT(problem.empty(), (problem + "\n" + res->body).c_str());
  return res->body;
}

}  // namespace

TEST_GROUP(ServerMetricsScrape) {
  lw::test::MosquittoFixture broker;
  lw::test::CrusherFolder folder{10, 5};
  Server server;
  void setup() override {
    broker.Start();
  }
};

TEST(ServerMetricsScrape, PrometheusParsesItAndTheReadingsCounterMovesWithIngest) {
  server.Start(broker.uri(), folder);
  httplib::Client http("127.0.0.1", server.port);
  const std::string before = Scrape(http);
  DOUBLES_EQUAL(0, ValueOf(before, "linerwatch_readings_stored_total"), 0);

  json body = {{"readings", json::array()}};
  const auto messages = lw::test::Messages(folder.bundle);
  for (size_t i = 0; i < 20; ++i) body["readings"].push_back(json::parse(messages[i].payload));
  body["readings"].push_back({{"sensor", messages[0].sensor},
                              {"seq", 999},
                              {"time", "not a time"},
                              {"thickness_mm", 50},
                              {"loops_intact", 50},
                              {"flags", 0},
                              {"battery_mv", 3300}});
  const auto posted = http.Post(("/api/v1/crushers/" + folder.id() + "/readings").c_str(), body.dump(), "application/json");
  CHECK(posted);
  LONGS_EQUAL_TEXT(200, posted->status, posted->body.c_str());

  // httplib counts a request after its response is written, so the POST's count can trail its
  // reply by a moment: scrape until it is there (bounded), then check everything on that scrape.
  const std::string post_series =
      "linerwatch_http_requests_total{method=\"POST\",route=\"/api/v1/crushers/{crusher}/readings\",code=\"200\"}";
  std::string after = Scrape(http);
  for (int i = 0; i < 100 && ValueOf(after, post_series) < 1; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    after = Scrape(http);
  }
  DOUBLES_EQUAL(20, ValueOf(after, "linerwatch_readings_stored_total"), 0);
  DOUBLES_EQUAL(21, ValueOf(after, "linerwatch_readings_ingested_total"), 0);
  DOUBLES_EQUAL(1, ValueOf(after, "linerwatch_readings_rejected_total{reason=\"time\"}"), 0);
  DOUBLES_EQUAL(20, ValueOf(after, "linerwatch_ingest_lag_seconds_count"), 0);
  DOUBLES_EQUAL(
      1,
      ValueOf(after,
              "linerwatch_http_requests_total{method=\"POST\",route=\"/api/v1/crushers/{crusher}/readings\",code=\"200\"}"),
      0);
  CHECK(ValueOf(after, "linerwatch_http_requests_total{method=\"GET\",route=\"/metrics\",code=\"200\"}") >= 1);
  CHECK(ValueOf(after, "linerwatch_store_bytes") > 0);
  // The same counts as /healthz (one source: the ingestor's counters).
  const auto health = http.Get("/healthz");
  CHECK(health);
  DOUBLES_EQUAL(json::parse(health->body)["readings_stored"].get<double>(), ValueOf(after, "linerwatch_readings_stored_total"),
                0);
  // A path nobody routes is counted under one label, with its 404.
  CHECK(http.Get("/no/such/thing"));
  CHECK(ValueOf(Scrape(http), "linerwatch_http_requests_total{method=\"GET\",route=\"other\",code=\"404\"}") >= 1);
}

TEST(ServerMetricsScrape, WithTokensTheScrapeNeedsTheReadScope) {
  const std::string tokens = folder.dir.File("tokens.json");
  std::ofstream(tokens)
      << json{{"tokens", {{{"name", "prometheus"}, {"sha256", lw::core::Sha256Hex("scrape-secret")}, {"scopes", {"read"}}}}}}
             .dump();
  server.Start(broker.uri(), folder, {"--tokens", tokens});
  httplib::Client http("127.0.0.1", server.port);
  const auto refused = http.Get("/metrics");
  CHECK(refused);
  LONGS_EQUAL(401, refused->status);
  STRCMP_EQUAL("missing or unknown bearer token", json::parse(refused->body)["error"].get<std::string>().c_str());
  Scrape(http, {{"Authorization", "Bearer scrape-secret"}});
}

// packaging/grafana/linerwatch.json's server panels: every expression parses as PromQL and every
// server metric it names is a family of this server's scrape (the gateway's are checked against
// the gateway, test_gateway_metrics_scrape). The checks themselves fail on a bad expression and an
// unknown name.
TEST(ServerMetricsScrape, TheGrafanaDashboardParsesAndNamesOnlyMetricsTheServerExports) {
  server.Start(broker.uri(), folder);
  httplib::Client http("127.0.0.1", server.port);
  const std::string text = Scrape(http);
  const lw::test::GrafanaDashboard dash = lw::test::ReadGrafanaDashboard(LW_GRAFANA_DASHBOARD);
  const std::string problem = lw::test::PromqlCheck(dash.panel_exprs);
  CHECK_TEXT(problem.empty(), problem.c_str());
  std::vector<std::string> exprs = dash.panel_exprs;
  exprs.insert(exprs.end(), dash.variable_exprs.begin(), dash.variable_exprs.end());
  const auto server_families =
      lw::test::MetricFamilies(exprs, [](const std::string& n) { return n.rfind("linerwatch_gateway_", 0) != 0; });
  CHECK(server_families.size() >= 10);  // the dashboard covers the server, not one metric of it
  std::string missing;
  for (const auto& n : lw::test::MissingFamilies(server_families, text)) missing += n + " ";
  CHECK_TEXT(missing.empty(), ("named by the dashboard, not exported by the server: " + missing).c_str());
  CHECK_FALSE(lw::test::PromqlCheck({"sum(rate(linerwatch_readings_stored_total[5m])"}).empty());
  CHECK(lw::test::MissingFamilies({"linerwatch_no_such_metric"}, text).size() == 1);
}
