#pragma once
// The coordinator radio as the gateway sees it (a gateway::ByteSink): decodes what the gateway
// writes back and keeps the acks (gateway unit tests, fuzz).
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "gateway/byte_sink.hpp"
#include "protocol/frame_decoder.hpp"
#include "protocol/sensor_payload.hpp"
#include "protocol/xbee_api.hpp"

namespace lw::test {

/// The radio side: decodes what the gateway writes back (Transmit Requests carrying acks).
class FakeRadio : public gateway::ByteSink {
 public:
  explicit FakeRadio(protocol::ApiMode mode) : decoder_(mode) {}
  struct SentAck {
    uint64_t dest64 = 0;
    protocol::Ack ack;
  };
  std::vector<SentAck> acks;
  size_t other_frames = 0;
  bool fail = false;
  /// Called before each write is accepted (e.g. to check the spool file at that moment).
  std::function<void()> on_write;

  std::vector<uint32_t> AckedSeqs() const {
    std::vector<uint32_t> out;
    for (const SentAck& a : acks) out.insert(out.end(), a.ack.seqs, a.ack.seqs + a.ack.count);
    return out;
  }

  bool Write(const uint8_t* data, size_t len) override {
    if (on_write) on_write();
    if (fail) return false;
    decoder_.Feed(data, len, [&](protocol::DecodeEvent event) {
      if (event != protocol::DecodeEvent::kFrame) return;
      protocol::TransmitRequest req;
      SentAck a;
      if (protocol::ParseTransmitRequest(decoder_.frame_data(), decoder_.frame_length(), &req) == protocol::Status::kOk &&
          protocol::DecodeAck(req.payload, req.payload_len, &a.ack) == protocol::PayloadStatus::kOk) {
        a.dest64 = req.dest64;
        acks.push_back(a);
      } else {
        ++other_frames;
      }
    });
    return true;
  }

 private:
  protocol::FrameDecoder decoder_;
};

}  // namespace lw::test
