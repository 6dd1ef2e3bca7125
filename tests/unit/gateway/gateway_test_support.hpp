#pragma once
// Helpers for the gateway unit tests: coordinator frames built with the shared protocol library,
// a temp directory, and fakes for the publisher and the radio.
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "gateway/byte_sink.hpp"
#include "mqtt/publisher.hpp"
#include "support/temp_directory.hpp"
#include "protocol/frame_decoder.hpp"
#include "protocol/sensor_payload.hpp"
#include "protocol/xbee_api.hpp"

namespace lw::gateway::test {


inline protocol::SensorRecord MakeRecord(uint32_t seq, uint16_t thickness_dmm = 870, uint16_t flags = 0) {
  protocol::SensorRecord r;
  r.seq = seq;
  r.age_s = 5;
  r.thickness_dmm = thickness_dmm;
  r.loops_intact = static_cast<uint8_t>(thickness_dmm / 10);
  r.flags = flags;
  r.battery_mv = 3550;
  r.temperature_c = 31;
  for (size_t i = 0; i < protocol::kMaxBitmapBytes; ++i) r.loop_bitmap[i] = 0xFF;
  return r;
}

/// Wire bytes of a 0x90 Receive Packet from `src64` carrying a readings payload.
inline std::vector<uint8_t> ReadingsFrame(protocol::ApiMode mode, uint64_t src64, uint32_t sensor_id,
                                          const std::vector<protocol::SensorRecord>& records, uint8_t ladder_loops = 16) {
  protocol::ReadingsHeader h;
  h.sensor_id = sensor_id;
  h.ladder_loops = ladder_loops;
  uint8_t payload[protocol::kMaxRfPayload];
  size_t payload_len = 0;
  if (protocol::EncodeReadings(h, records.data(), records.size(), payload, sizeof payload, &payload_len) !=
      protocol::PayloadStatus::kOk) {
    return {};
  }
  protocol::ReceivePacket rx;
  rx.src64 = src64;
  rx.src16 = 0x1234;
  rx.options = 0x01;
  rx.payload = payload;
  rx.payload_len = payload_len;
  uint8_t frame[protocol::kMaxFrameData];
  size_t frame_len = 0;
  if (protocol::BuildReceivePacket(rx, frame, sizeof frame, &frame_len) != protocol::Status::kOk) return {};
  std::vector<uint8_t> wire(protocol::kMaxWireFrame);
  wire.resize(protocol::EncodeFrame(mode, frame, frame_len, wire.data(), wire.size()));
  return wire;
}

/// Wire bytes of any frame data.
inline std::vector<uint8_t> Wire(protocol::ApiMode mode, const std::vector<uint8_t>& frame_data) {
  std::vector<uint8_t> wire(protocol::kMaxWireFrame);
  wire.resize(protocol::EncodeFrame(mode, frame_data.data(), frame_data.size(), wire.data(), wire.size()));
  return wire;
}

/// Publisher fake: records every message; connection and refusal are test controls.
class FakePublisher : public mqtt::Publisher {
 public:
  using OutMessage = mqtt::OutMessage;
  std::vector<OutMessage> sent;
  bool connected = true;
  bool refuse = false;

  std::vector<OutMessage> SentOn(const std::string& topic_suffix) const {
    std::vector<OutMessage> out;
    for (const OutMessage& m : sent) {
      if (m.topic.size() >= topic_suffix.size() &&
          m.topic.compare(m.topic.size() - topic_suffix.size(), topic_suffix.size(), topic_suffix) == 0) {
        out.push_back(m);
      }
    }
    return out;
  }

 private:
  bool DoPublish(const OutMessage& message) override {
    if (!connected || refuse) return false;
    sent.push_back(message);
    return true;
  }
  bool DoIsConnected() const override { return connected; }
};

/// The radio side: decodes what the gateway writes back (Transmit Requests carrying acks).
class FakeRadio : public ByteSink {
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

}  // namespace lw::gateway::test
