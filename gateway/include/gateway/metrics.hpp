#pragma once
/// The gateway's Prometheus metrics (`--metrics HOST:PORT`, docs/gateway.md, *Metrics*): its
/// counters (the same the `gateway/stats` message carries) in the text format 0.0.4, written by
/// the writer the server uses too (core/prometheus.hpp).
#include <string>

#include "gateway/gateway.hpp"

namespace lw::gateway {

/// The exposition text of `gateway`'s counters, spool depth and the MQTT connection state. Call
/// it on the thread that drives the Gateway (its counters are that thread's).
std::string MetricsText(const Gateway& gateway, bool mqtt_connected);

}  // namespace lw::gateway
