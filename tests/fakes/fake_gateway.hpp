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
  /// With `rtc`, each record's sample time (arrival - age_s) identifies it, so a seq handed out
  /// twice for different samples is caught even when the contents happen to match.
  explicit FakeGateway(hal::host::HostRadio& radio, const hal::host::HostRtc* rtc = nullptr) : radio_(radio), rtc_(rtc) {
    radio_.set_on_deliver([this](uint64_t, const uint8_t* p, size_t n) { OnDeliver(p, n); });
  }
  void set_acking(bool on) { acking_ = on; }

  std::map<uint32_t, protocol::SensorRecord> records;  // by seq, first copy kept
  std::vector<uint32_t> arrival_order;                 // seqs as they arrived (with duplicates)
  uint16_t last_dropped_total = 0;
  uint32_t frames = 0;
  uint32_t bad_payloads = 0;
  /// Arrivals whose seq was seen before with a different sample (time, thickness, flags): a
  /// reused sequence number, which the real gateway would discard as a duplicate.
  uint32_t seq_conflicts = 0;

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
      const uint32_t sampled_at = rtc_ ? rtc_->now() - recs[i].age_s : 0;
      const auto [it, inserted] = records.emplace(recs[i].seq, recs[i]);
      if (inserted) {
        sampled_at_[recs[i].seq] = sampled_at;
      } else if (sampled_at_[recs[i].seq] != sampled_at || it->second.loops_intact != recs[i].loops_intact ||
                 it->second.flags != recs[i].flags) {
        ++seq_conflicts;
      }
      arrival_order.push_back(recs[i].seq);
      ack.seqs[ack.count++] = recs[i].seq;
    }
    if (!acking_) return;
    uint8_t buf[protocol::kMaxRfPayload];
    size_t len = 0;
    if (protocol::EncodeAck(ack, buf, sizeof buf, &len) == protocol::PayloadStatus::kOk) radio_.Inject(buf, len);
  }
  hal::host::HostRadio& radio_;
  const hal::host::HostRtc* rtc_;
  std::map<uint32_t, uint32_t> sampled_at_;
  bool acking_ = true;
};

}  // namespace lw::test
