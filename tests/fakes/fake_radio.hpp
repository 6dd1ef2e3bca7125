#pragma once
// The coordinator radio as the gateway sees it (a gateway::ByteSink): decodes what the gateway
// writes back and keeps the acks (gateway unit tests, fuzz). With `np` set it answers the local AT
// queries NP and EE as a module would (the answers wait in TakeAnswers() for the test to feed back),
// and it refuses (does not keep) an ack whose payload is above the limit those answers imply.
#include <cstddef>
#include <algorithm>
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
  explicit FakeRadio(protocol::ApiMode mode) : mode_(mode), decoder_(mode) {}
  struct SentAck {
    uint64_t dest64 = 0;
    protocol::Ack ack;
  };
  std::vector<SentAck> acks;
  size_t other_frames = 0;
  bool fail = false;
  int np = -1;  ///< AT NP answer; -1: AT commands get no answer
  int ee = 0;   ///< AT EE answer
  size_t at_queries = 0;
  size_t acks_too_large = 0;  ///< acks above protocol::RfPayloadLimit(np, ee): refused, not kept
  size_t largest_ack_payload = 0;

  /// The module's answers to the AT queries written so far (wire bytes for Gateway::OnBytes).
  std::vector<uint8_t> TakeAnswers() {
    std::vector<uint8_t> out;
    out.swap(answers_);
    return out;
  }
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
      protocol::AtCommand cmd;
      SentAck a;
      if (protocol::ParseAtCommand(decoder_.frame_data(), decoder_.frame_length(), &cmd) == protocol::Status::kOk) {
        Answer(cmd);
        return;
      }
      const bool is_request =
          protocol::ParseTransmitRequest(decoder_.frame_data(), decoder_.frame_length(), &req) == protocol::Status::kOk;
      if (is_request) largest_ack_payload = std::max(largest_ack_payload, req.payload_len);
      if (is_request && np >= 0 && req.payload_len > protocol::RfPayloadLimit(np, ee)) {
        ++acks_too_large;
        return;
      }
      if (is_request && protocol::DecodeAck(req.payload, req.payload_len, &a.ack) == protocol::PayloadStatus::kOk) {
        a.dest64 = req.dest64;
        acks.push_back(a);
      } else {
        ++other_frames;
      }
    });
    return true;
  }

 private:
  void Answer(const protocol::AtCommand& cmd) {
    ++at_queries;
    if (np < 0 || cmd.frame_id == 0) return;
    protocol::AtCommandResponse rsp;
    rsp.frame_id = cmd.frame_id;
    rsp.command[0] = cmd.command[0];
    rsp.command[1] = cmd.command[1];
    const uint8_t np_value[2] = {0, static_cast<uint8_t>(np)};
    const uint8_t ee_value[1] = {static_cast<uint8_t>(ee)};
    if (cmd.command[0] == 'N' && cmd.command[1] == 'P') {
      rsp.data = np_value;
      rsp.data_len = 2;
    } else if (cmd.command[0] == 'E' && cmd.command[1] == 'E') {
      rsp.data = ee_value;
      rsp.data_len = 1;
    } else {
      rsp.status = static_cast<uint8_t>(protocol::AtStatus::kInvalidCommand);
    }
    uint8_t frame[16], wire[40];
    size_t n = 0;
    if (protocol::BuildAtCommandResponse(rsp, frame, sizeof frame, &n) != protocol::Status::kOk) return;
    const size_t w = protocol::EncodeFrame(mode_, frame, n, wire, sizeof wire);
    answers_.insert(answers_.end(), wire, wire + w);
  }
  protocol::ApiMode mode_;
  protocol::FrameDecoder decoder_;
  std::vector<uint8_t> answers_;
};

}  // namespace lw::test
