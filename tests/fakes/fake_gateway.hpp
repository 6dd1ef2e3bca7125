#pragma once
// A coordinator-side fake for firmware tests: decodes what a HostRadio delivers with the shared
// protocol library, keeps every record by seq, and acks (optionally) like the real gateway.
#include <cstdint>
#include <map>
#include <vector>

#include "hal/host/host_board.hpp"
#include "protocol/sensor_payload.hpp"

namespace lw::test {

class FakeGateway {
 public:
  explicit FakeGateway(hal::host::HostRadio& radio) : radio_(radio) {
    radio_.set_on_deliver([this](uint64_t, const uint8_t* p, size_t n) { OnDeliver(p, n); });
  }
  void set_acking(bool on) { acking_ = on; }

  std::map<uint32_t, protocol::SensorRecord> records;  // by seq, first copy kept
  std::vector<uint32_t> arrival_order;                   // seqs as they arrived (with duplicates)
  uint16_t last_dropped_total = 0;
  uint32_t frames = 0;
  uint32_t bad_payloads = 0;

 private:
  void OnDeliver(const uint8_t* p, size_t n) {
    ++frames;
    protocol::ReadingsHeader h;
    protocol::SensorRecord recs[8];
    size_t count = 0;
    if (protocol::DecodeReadings(p, n, &h, recs, 8, &count) != protocol::PayloadStatus::kOk) {
      ++bad_payloads;
      return;
    }
    last_dropped_total = h.dropped_total;
    protocol::Ack ack;
    ack.sensor_id = h.sensor_id;
    for (size_t i = 0; i < count; ++i) {
      records.emplace(recs[i].seq, recs[i]);
      arrival_order.push_back(recs[i].seq);
      ack.seqs[ack.count++] = recs[i].seq;
    }
    if (!acking_) return;
    uint8_t buf[protocol::kMaxRfPayload];
    size_t len = 0;
    if (protocol::EncodeAck(ack, buf, sizeof buf, &len) == protocol::PayloadStatus::kOk) radio_.Inject(buf, len);
  }
  hal::host::HostRadio& radio_;
  bool acking_ = true;
};

}  // namespace lw::test
