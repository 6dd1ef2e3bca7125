// The server's GET /metrics (server/metrics.hpp) through rest::Resources: the ingest counters the
// health JSON also shows, rejections by reason class, HTTP requests by route template and status,
// and the wear worker's state.
#include <string>

#include "core/prometheus.hpp"
#include "server/metrics.hpp"
#include "server/rest.hpp"
#include "unit/server/server_fixture.hpp"

#include <CppUTest/TestHarness.h>  // last

using namespace lw::server;
using nlohmann::json;

namespace {

lw::test::CrusherFolder& Folder() {
  static lw::test::CrusherFolder f(10, 5);
  return f;
}

struct Fixture {
  lw::test::ServerParts parts{Folder().crushers, false};
  ServerMetrics metrics{parts.dir.File("db.sqlite")};
  std::unique_ptr<rest::Resources> resources;
  Fixture() {
    parts.ctx.metrics = &metrics;
    resources = std::make_unique<rest::Resources>(parts.ctx);
  }
  rest::Response Scrape() { return resources->Call(rest::Resources::Find(rest::Method::kGet, "/metrics"), {}); }
  std::string Text() {
    const rest::Response r = Scrape();
    LONGS_EQUAL(200, r.status);
    CHECK(r.raw.has_value());
    return r.raw->content;
  }
};

/// The value of the sample `series` (name with its labels, as written) in `text`; -1 when absent.
double ValueOf(const std::string& text, const std::string& series) {
  const size_t at = text.find("\n" + series + " ");
  if (at == std::string::npos) return -1;
  return std::stod(text.substr(at + series.size() + 2));
}

/// A valid reading message of the folder (its first), with `edit` applied to the payload.
Incoming Message(const std::function<void(json&)>& edit, const std::string& site = "site1") {
  Incoming m = lw::test::Messages(Folder().bundle, site).front();
  json j = json::parse(m.payload);
  edit(j);
  m.payload = j.dump();
  return m;
}

}  // namespace

TEST_GROUP(ServerMetrics){};

TEST(ServerMetrics, TheRouteServesTheTextFormatAndNeedsTheReadScope) {
  Fixture f;
  const rest::Response r = f.Scrape();
  LONGS_EQUAL(200, r.status);
  STRCMP_EQUAL("text/plain; version=0.0.4; charset=utf-8", r.raw->content_type.c_str());
  CHECK(r.raw->content.rfind("# HELP linerwatch_build_info ", 0) == 0);
  CHECK(r.raw->content.find("\nlinerwatch_build_info{program=\"linerwatch-server\",version=\"") != std::string::npos);
  CHECK(rest::Scope::kRead == rest::RequiredScope("GET", "/metrics"));
  // A server without metrics (none made) says so.
  lw::test::ServerParts bare(Folder().crushers, false);
  rest::Resources none(bare.ctx);
  const rest::Response off = none.Call(rest::Resources::Find(rest::Method::kGet, "/metrics"), {});
  LONGS_EQUAL(503, off.status);
  STRCMP_EQUAL("metrics are not kept by this server", off.json["error"].get<std::string>().c_str());
}

TEST(ServerMetrics, IngestCountersMoveWithPostedReadingsAsHealthsDo) {
  Fixture f;
  std::string text = f.Text();
  DOUBLES_EQUAL(0, ValueOf(text, "linerwatch_readings_stored_total"), 0);
  json body = {{"readings", json::array()}};
  const auto messages = lw::test::Messages(Folder().bundle);
  for (const auto& m : messages) body["readings"].push_back(json::parse(m.payload));
  const std::string posted = body.dump();
  rest::Request post;
  post.path = {Folder().id()};
  post.body = posted;
  LONGS_EQUAL(200,
              f.resources->Call(rest::Resources::Find(rest::Method::kPost, "/api/v1/crushers/{crusher}/readings"), post).status);
  text = f.Text();
  const IngestCounters c = f.parts.ingestor->Counters();
  LONGS_EQUAL(messages.size(), c.stored);
  DOUBLES_EQUAL(static_cast<double>(c.stored), ValueOf(text, "linerwatch_readings_stored_total"), 0);
  DOUBLES_EQUAL(static_cast<double>(c.stored), ValueOf(text, "linerwatch_readings_ingested_total"), 0);
  DOUBLES_EQUAL(1, ValueOf(text, "linerwatch_ingest_commits_total"), 0);
  DOUBLES_EQUAL(0, ValueOf(text, "linerwatch_readings_duplicates_total"), 0);
}

TEST(ServerMetrics, RejectedReadingsAreCountedByReasonClass) {
  Fixture f;
  Ingestor& ingest = *f.parts.ingestor;
  ingest.Ingest({Message([](json&) {})});  // binds the crusher to site1
  Incoming malformed = Message([](json&) {});
  malformed.payload = "{not json";
  Incoming mismatch = Message([](json& j) { j["sensor"] = "not-the-topics"; });
  Incoming unknown_crusher = Message([](json&) {});
  unknown_crusher.crusher = "nope";
  Incoming unknown_sensor = Message([](json& j) { j["sensor"] = "9999"; });
  unknown_sensor.sensor = "9999";
  const IngestResult r = ingest.Ingest({malformed, mismatch, unknown_crusher, unknown_sensor,
                                        Message([](json& j) { j["time"] = "2000-01-01T00:00:00Z"; }),
                                        Message([](json& j) { j["time"] = "yesterday"; }),
                                        Message([](json& j) { j["thickness_mm"] = 999; }), Message([](json&) {}, "other-site")});
  LONGS_EQUAL(7, r.rejected);
  LONGS_EQUAL(1, r.held);  // the unknown crusher: not acked, its gateway publishes it again
  const std::string text = f.Text();
  const std::pair<const char*, double> expected[] = {{"malformed", 1}, {"sensor_mismatch", 1}, {"unknown_sensor", 1}, {"time", 2},
                                                     {"thickness", 1}, {"foreign_site", 1},    {"internal", 0}};
  for (const auto& [reason, n] : expected) {
    DOUBLES_EQUAL_TEXT(n, ValueOf(text, std::string("linerwatch_readings_rejected_total{reason=\"") + reason + "\"}"), 0, reason);
  }
  LONGS_EQUAL(7, ingest.Counters().rejected);
  const std::pair<const char*, double> held[] = {{"unknown_crusher", 1}, {"future", 0}, {"no_site", 0}};
  for (const auto& [reason, n] : held) {
    DOUBLES_EQUAL_TEXT(n, ValueOf(text, std::string("linerwatch_readings_held_total{reason=\"") + reason + "\"}"), 0, reason);
  }
}

TEST(ServerMetrics, RequestsAreCountedByTheirRouteTemplateAndStatus) {
  STRCMP_EQUAL("/api/v1/crushers/{crusher}/wear", RouteLabel("/api/v1/crushers/c1/wear").c_str());
  STRCMP_EQUAL("/api/v1/crushers/{crusher}/sensors/{sensor}/readings",
               RouteLabel("/api/v1/crushers/c1/sensors/1001/readings").c_str());
  STRCMP_EQUAL("/api/v1/crushers/{crusher}", RouteLabel("/api/v1/crushers/c1").c_str());
  STRCMP_EQUAL("/metrics", RouteLabel("/metrics").c_str());
  STRCMP_EQUAL("/", RouteLabel("/").c_str());
  STRCMP_EQUAL("/assets", RouteLabel("/assets/index-1234.js").c_str());
  STRCMP_EQUAL("other", RouteLabel("/api/v1/crushers//wear").c_str());
  STRCMP_EQUAL("other", RouteLabel("/api/v1/crushers/c1/wear/extra").c_str());
  STRCMP_EQUAL("other", RouteLabel("/wp-login.php").c_str());
  Fixture f;
  f.metrics.CountHttp("GET", "/api/v1/crushers/c1", 200);
  f.metrics.CountHttp("GET", "/api/v1/crushers/c2", 200);
  f.metrics.CountHttp("GET", "/api/v1/crushers/c2", 404);
  f.metrics.CountHttp("BREW", "/pot\"\n", 404);
  const std::string text = f.Text();
  DOUBLES_EQUAL(
      2, ValueOf(text, "linerwatch_http_requests_total{method=\"GET\",route=\"/api/v1/crushers/{crusher}\",code=\"200\"}"), 0);
  DOUBLES_EQUAL(
      1, ValueOf(text, "linerwatch_http_requests_total{method=\"GET\",route=\"/api/v1/crushers/{crusher}\",code=\"404\"}"), 0);
  DOUBLES_EQUAL(1, ValueOf(text, "linerwatch_http_requests_total{method=\"other\",route=\"other\",code=\"404\"}"), 0);
}

TEST(ServerMetrics, TheWearLagGrowsUntilARecomputeSucceeds) {
  Fixture f;
  const std::string c = Folder().id();
  const std::string lag = "linerwatch_wear_lag_seconds{crusher=\"" + c + "\"}";
  const std::string ok = "linerwatch_wear_runs_total{crusher=\"" + c + "\",result=\"ok\"}";
  const std::string failed = "linerwatch_wear_runs_total{crusher=\"" + c + "\",result=\"error\"}";
  const std::string last = "linerwatch_wear_last_success_timestamp_seconds{crusher=\"" + c + "\"}";
  const auto render = [&](int64_t now_ms) { return f.metrics.Render(*f.parts.ingestor, *f.parts.registry, 0, now_ms); };
  DOUBLES_EQUAL(0, ValueOf(render(1000), lag), 0);
  f.metrics.WearChanged(c, 1000);
  DOUBLES_EQUAL(3, ValueOf(render(4000), lag), 0);
  f.metrics.WearTaken(c);
  f.metrics.WearChanged(c, 2000);  // more readings while the recompute runs
  f.metrics.WearDone(c, false, 0.5, 5000);
  DOUBLES_EQUAL(5, ValueOf(render(6000), lag), 0);  // the failed recompute leaves the oldest change waiting
  f.metrics.WearTaken(c);
  f.metrics.WearDone(c, true, 0.5, 7000);
  std::string text = render(8000);
  DOUBLES_EQUAL(0, ValueOf(text, lag), 0);
  DOUBLES_EQUAL(1, ValueOf(text, ok), 0);
  DOUBLES_EQUAL(1, ValueOf(text, failed), 0);
  DOUBLES_EQUAL(7, ValueOf(text, last), 0);
  DOUBLES_EQUAL(2, ValueOf(text, "linerwatch_wear_duration_seconds_count"), 0);
}

TEST(ServerMetrics, IngestLagIsTheCommitTimeMinusTheMeasuredTime) {
  Fixture f;
  IngestResult r;
  StoredReading a, b;
  a.time_s = 1000;
  b.time_s = 1000 - 7200;
  r.new_readings = {a, b};
  f.metrics.ObserveCommitted(r, 1010);
  const std::string text = f.Text();
  DOUBLES_EQUAL(2, ValueOf(text, "linerwatch_ingest_lag_seconds_count"), 0);
  DOUBLES_EQUAL(7220, ValueOf(text, "linerwatch_ingest_lag_seconds_sum"), 0);
  DOUBLES_EQUAL(1, ValueOf(text, "linerwatch_ingest_lag_seconds_bucket{le=\"15\"}"), 0);
  DOUBLES_EQUAL(2, ValueOf(text, "linerwatch_ingest_lag_seconds_bucket{le=\"14400\"}"), 0);
}
