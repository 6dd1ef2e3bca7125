// The real linerwatch-gateway's --metrics, scraped over loopback as Prometheus would: the text
// passes Prometheus' own parser and linter (promtool check metrics), and the frame, spool and
// publication counters move when a sensor's readings frame arrives on the serial line.
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "protocol/sensor_payload.hpp"
#include "protocol/xbee_api.hpp"
#include "support/grafana.hpp"
#include "support/mosquitto_fixture.hpp"
#include "support/promtool.hpp"
#include "support/raw_pty.hpp"

#include <httplib.h>

#include <CppUTest/TestHarness.h>  // last

namespace pr = lw::protocol;

namespace {

/// The value of the sample `series` (name with its labels, as written) in `text`; -1 when absent.
double ValueOf(const std::string& text, const std::string& series) {
  const size_t at = text.find("\n" + series + " ");
  if (at == std::string::npos) return -1;
  return std::stod(text.substr(at + series.size() + 2));
}

/// One readings frame of sensor 1001 with records `first`, `first` + 1, as a coordinator writes it.
std::string ReadingsFrame(uint32_t first) {
  pr::ReadingsHeader h;
  h.sensor_id = 1001;
  h.ladder_loops = 100;
  pr::SensorRecord recs[2];
  for (uint32_t i = 0; i < 2; ++i) {
    recs[i].seq = first + i;
    recs[i].thickness_dmm = 900;
    recs[i].loops_intact = 90;
    recs[i].battery_mv = 3600;
  }
  uint8_t payload[pr::kMaxRfPayload];
  size_t payload_len = 0;
  CHECK(pr::EncodeReadings(h, recs, 2, payload, sizeof payload, &payload_len) == pr::PayloadStatus::kOk);
  const pr::ReceivePacket rx{0x0013A20040000001ull, 0x2001, 0x01, payload, payload_len};
  uint8_t wire[pr::kMaxWireFrame];
  const size_t n = pr::EncodeReceivePacket(pr::ApiMode::kEscaped, rx, wire, sizeof wire);
  return std::string(reinterpret_cast<const char*>(wire), n);
}

}  // namespace

TEST_GROUP(GatewayMetrics) {
  lw::test::MosquittoFixture broker;
  lw::test::TempDirectory dir{"lw-gw-metrics"};
  lw::test::RawPty pty;
  lw::test::ChildProcess gateway;
  void setup() override {
    broker.Start();
  }
};

TEST(GatewayMetrics, PrometheusParsesItAndTheCountersMoveWithAFrame) {
  const int port = lw::test::FreeLoopbackPort();
  const std::string log = dir.File("gateway.log");
  gateway.Start({LW_GATEWAY_BIN, "--serial", pty.slave_name(), "--broker", broker.uri(), "--site", "s1", "--crusher", "c1",
                 "--spool", dir.File("spool.sqlite"), "--metrics", "127.0.0.1:" + std::to_string(port)},
                log);
  for (int i = 0; i < 600 && !lw::test::PortAccepts(port); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  CHECK_TEXT(lw::test::PortAccepts(port), lw::test::FileTail(log).c_str());
  httplib::Client http("127.0.0.1", port);
  const auto scrape = [&] {
    const auto res = http.Get("/metrics");
    CHECK(res);
    LONGS_EQUAL_TEXT(200, res->status, res->body.c_str());
    STRCMP_EQUAL("text/plain; version=0.0.4; charset=utf-8", res->get_header_value("Content-Type").c_str());
    const std::string problem = lw::test::PromtoolCheck(res->body);
    CHECK_TEXT(problem.empty(), (problem + "\n" + res->body).c_str());
    return res->body;
  };
  std::string text = scrape();
  DOUBLES_EQUAL(0, ValueOf(text, "linerwatch_gateway_frames_received_total"), 0);
  DOUBLES_EQUAL(0, ValueOf(text, "linerwatch_gateway_records_spooled_total"), 0);
  CHECK(text.find("\nlinerwatch_build_info{program=\"linerwatch-gateway\",version=\"") != std::string::npos);

  const std::string frame = ReadingsFrame(1);
  CHECK(::write(pty.master(), frame.data(), frame.size()) == static_cast<ssize_t>(frame.size()));
  const unsigned char bad_checksum[] = {0x7e, 0x00, 0x02, 0x90, 0x00, 0x00};
  CHECK(::write(pty.master(), bad_checksum, sizeof bad_checksum) == static_cast<ssize_t>(sizeof bad_checksum));
  // Published once the broker connection is up: one record of the sensor at a time (--window 1),
  // and no server acks here, so both records stay spooled. Bounded by 60 scrapes, not by a time.
  for (int i = 0; i < 60 && (ValueOf(text, "linerwatch_gateway_published_total") < 1 ||
                             ValueOf(text, "linerwatch_gateway_frame_errors_total{reason=\"checksum\"}") < 1);
       ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
    text = scrape();
  }
  DOUBLES_EQUAL_TEXT(1, ValueOf(text, "linerwatch_gateway_frames_received_total"), 0, text.c_str());
  DOUBLES_EQUAL(2, ValueOf(text, "linerwatch_gateway_records_spooled_total"), 0);
  DOUBLES_EQUAL(2, ValueOf(text, "linerwatch_gateway_spool_depth"), 0);
  DOUBLES_EQUAL(1, ValueOf(text, "linerwatch_gateway_published_total"), 0);
  DOUBLES_EQUAL(1, ValueOf(text, "linerwatch_gateway_in_flight"), 0);
  DOUBLES_EQUAL(1, ValueOf(text, "linerwatch_gateway_frame_errors_total{reason=\"checksum\"}"), 0);
  DOUBLES_EQUAL(1, ValueOf(text, "linerwatch_gateway_mqtt_connected"), 0);
  DOUBLES_EQUAL(1, ValueOf(text, "linerwatch_gateway_sensor_acks_total"), 0);
  DOUBLES_EQUAL(0, ValueOf(text, "linerwatch_gateway_acked_total"), 0);

  // packaging/grafana/linerwatch.json's gateway panels name only families this scrape declares
  // (their PromQL is parsed by test_server_metrics_scrape).
  const auto gateway_families =
      lw::test::MetricFamilies(lw::test::ReadGrafanaDashboard(LW_GRAFANA_DASHBOARD).panel_exprs,
                               [](const std::string& n) { return n.rfind("linerwatch_gateway_", 0) == 0; });
  CHECK(gateway_families.size() >= 5);
  std::string missing;
  for (const auto& n : lw::test::MissingFamilies(gateway_families, text)) missing += n + " ";
  CHECK_TEXT(missing.empty(), ("named by the dashboard, not exported by the gateway: " + missing).c_str());

  const auto other = http.Get("/other");
  CHECK(other);
  LONGS_EQUAL(404, other->status);
  CHECK(nlohmann::json::parse(other->body).contains("error"));
}
