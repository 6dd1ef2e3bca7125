#include "gateway/metrics.hpp"

#include "core/prometheus.hpp"

namespace lw::gateway {

using core::prometheus::Type;

namespace {

void Count(core::prometheus::Writer& w, const char* name, const char* help, uint64_t value) {
  w.Counter(name, help, static_cast<double>(value));
}

void RadioMetrics(core::prometheus::Writer& w, const Gateway& g) {
  const protocol::DecoderCounters& d = g.decoder_counters();
  const GatewayCounters& c = g.counters();
  Count(w, "linerwatch_gateway_frames_received_total", "API frames from the coordinator with a valid checksum", d.frames_ok);
  w.Family("linerwatch_gateway_frame_errors_total",
           "Frames from the coordinator that could not be used, by reason: checksum, escape (API mode 2), length, "
           "truncated, malformed (a known type that failed to parse), bad_payload (a sensor payload that failed to "
           "decode), unknown_payload, unknown_frame (a type the gateway does not handle)",
           Type::kCounter);
  const std::pair<const char*, uint64_t> errors[] = {
      {"checksum", d.checksum_errors},         {"escape", d.escape_errors},        {"length", d.length_errors},
      {"truncated", d.truncated_frames},       {"malformed", c.malformed_frames},  {"bad_payload", c.bad_payloads},
      {"unknown_payload", c.unknown_payloads}, {"unknown_frame", c.unknown_frames}};
  for (const auto& [reason, n] : errors) w.Sample({{"reason", reason}}, static_cast<double>(n));
  Count(w, "linerwatch_gateway_bytes_discarded_total", "Serial bytes outside any frame", d.bytes_discarded);
  w.Family("linerwatch_gateway_radio_errors_total",
           "Radio errors: tx_failure (a Transmit Status other than success for an ack to a sensor), ack_write (the "
           "ack could not be written to the serial port)",
           Type::kCounter);
  w.Sample({{"kind", "tx_failure"}}, static_cast<double>(c.tx_failures));
  w.Sample({{"kind", "ack_write"}}, static_cast<double>(c.ack_write_errors));
  Count(w, "linerwatch_gateway_sensor_acks_total", "Acks sent to sensors over the radio", c.acks_sent);
  Count(w, "linerwatch_gateway_devices_refused_total", "New radio devices not registered: the registry is full",
        c.devices_refused);
}

void SpoolAndMqttMetrics(core::prometheus::Writer& w, const Gateway& g, bool mqtt_connected) {
  const GatewayCounters& c = g.counters();
  Count(w, "linerwatch_gateway_records_received_total", "Sensor records decoded from readings frames (retransmissions too)",
        c.records_received);
  Count(w, "linerwatch_gateway_records_spooled_total", "New sensor records stored in the spool", c.records_spooled);
  Count(w, "linerwatch_gateway_records_duplicate_total", "Retransmitted records already in the spool", c.records_duplicate);
  Count(w, "linerwatch_gateway_records_rejected_total", "Records not stored (and not acked to the sensor): the spool is full",
        c.records_rejected);
  Count(w, "linerwatch_gateway_spool_errors_total", "SQLite failures of the spool (the records concerned are not acked)",
        c.spool_errors);
  w.Gauge("linerwatch_gateway_spool_depth", "Records in the spool waiting for the server's commit ack",
          static_cast<double>(g.spool_depth()));
  w.Gauge("linerwatch_gateway_in_flight", "Records published and awaiting a commit ack", static_cast<double>(g.in_flight()));
  Count(w, "linerwatch_gateway_published_total", "First publications of a record on MQTT", c.published);
  Count(w, "linerwatch_gateway_republished_total", "Publications of a record again (after a reconnect or --republish-after)",
        c.republished);
  Count(w, "linerwatch_gateway_publish_refused_total", "Publications the MQTT client refused to take (tried again later)",
        c.publish_refused);
  Count(w, "linerwatch_gateway_acked_total", "Records the server confirmed committed (then deleted from the spool)", c.committed);
  Count(w, "linerwatch_gateway_bad_commit_acks_total", "Commit ack messages that failed to decode", c.bad_commit_acks);
  w.Counter(
      "linerwatch_gateway_commit_latency_seconds_total",
      "Receive-to-commit-ack time summed over the acked records: its rate over linerwatch_gateway_acked_total's is the mean",
      static_cast<double>(c.latency_sum_ms) / 1000);
  w.Gauge("linerwatch_gateway_mqtt_connected", "1 while the MQTT client is connected to the broker", mqtt_connected ? 1 : 0);
  Count(w, "linerwatch_gateway_mqtt_connects_total", "Connections made to the broker", c.connects);
  Count(w, "linerwatch_gateway_link_resets_total", "Reconnects forced because the connection carried nothing of QoS 1",
        c.link_resets);
}

}  // namespace

std::string MetricsText(const Gateway& gateway, bool mqtt_connected) {
  core::prometheus::Writer w;
  w.Family("linerwatch_build_info", "The program's version (the value is always 1)", Type::kGauge);
  w.Sample({{"program", "linerwatch-gateway"}, {"version", LW_VERSION}}, 1);
  RadioMetrics(w, gateway);
  SpoolAndMqttMetrics(w, gateway, mqtt_connected);
  return w.Take();
}

}  // namespace lw::gateway
