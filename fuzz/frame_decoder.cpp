// XBee API frame decoder (protocol/frame_decoder.hpp) fed arbitrary serial bytes, in the API mode
// of LW_FUZZ_API_MODE (1 or 2; one binary per mode), and every frame parser on what it delivers.
// Properties: a delivered frame fits kMaxFrameData and counts in frames_ok; re-encoding it in either
// mode and decoding that gives the same frame; every parser that accepts a frame builds the same
// bytes back; in mode 2 a valid frame sent after any bytes is delivered (0x7E always starts a frame).
#include <cstring>
#include <string>

#include "fuzz_support.hpp"
#include "protocol/frame_decoder.hpp"
#include "protocol/sensor_payload.hpp"
#include "protocol/xbee_api.hpp"

namespace {

using namespace lw::protocol;
using lw::fuzz::Check;

constexpr ApiMode kMode = LW_FUZZ_API_MODE == 1 ? ApiMode::kUnescaped : ApiMode::kEscaped;

bool Same(const uint8_t* a, size_t a_len, const uint8_t* b, size_t b_len) {
  return a_len == b_len && std::memcmp(a, b, a_len) == 0;
}

/// Encodes `frame` in `mode`, decodes it on a fresh decoder: exactly one event, the same frame.
void CheckRoundTrip(ApiMode mode, const uint8_t* frame, size_t len) {
  uint8_t wire[kMaxWireFrame];
  const size_t n = EncodeFrame(mode, frame, len, wire, sizeof wire);
  Check(n > 0, "EncodeFrame refused a frame the decoder delivered");
  FrameDecoder d(mode);
  for (size_t i = 0; i < n; ++i) {
    const DecodeEvent e = d.Feed(wire[i]);
    if (i + 1 < n) {
      Check(e == DecodeEvent::kNone, "event before the end of a re-encoded frame");
    } else {
      Check(e == DecodeEvent::kFrame, "a re-encoded frame was not delivered");
      Check(Same(d.frame_data(), d.frame_length(), frame, len), "a re-encoded frame came back different");
    }
  }
}

/// Each parser that accepts the frame: the builder gives the same bytes back (parsers ignore
/// nothing but, for fixed-size frames, trailing bytes).
void CheckParsers(const uint8_t* f, size_t len) {
  uint8_t out[kMaxFrameData];
  size_t w = 0;
  TransmitRequest tr;
  if (ParseTransmitRequest(f, len, &tr) == Status::kOk) {
    Check(tr.payload >= f && tr.payload + tr.payload_len == f + len, "0x10 payload outside the frame");
    Check(BuildTransmitRequest(tr, out, sizeof out, &w) == Status::kOk && Same(out, w, f, len), "0x10 does not round-trip");
  }
  TransmitStatus ts;
  if (ParseTransmitStatus(f, len, &ts) == Status::kOk) {
    Check(BuildTransmitStatus(ts, out, sizeof out, &w) == Status::kOk && w <= len && Same(out, w, f, w),
          "0x8B does not round-trip");
  }
  ReceivePacket rx;
  if (ParseReceivePacket(f, len, &rx) == Status::kOk) {
    Check(rx.payload >= f && rx.payload + rx.payload_len == f + len, "0x90 payload outside the frame");
    Check(BuildReceivePacket(rx, out, sizeof out, &w) == Status::kOk && Same(out, w, f, len), "0x90 does not round-trip");
    ReadingsHeader h;
    SensorRecord records[8];
    size_t count = 0;
    (void)DecodeReadings(rx.payload, rx.payload_len, &h, records, 8, &count);
    Check(count <= 8, "DecodeReadings wrote past its capacity");
    Ack ack;
    (void)DecodeAck(rx.payload, rx.payload_len, &ack);
  }
  ModemStatus ms;
  if (ParseModemStatus(f, len, &ms) == Status::kOk) {
    Check(ModemStatusName(ms.status) != nullptr, "ModemStatusName returned null");
    Check(BuildModemStatus(ms, out, sizeof out, &w) == Status::kOk && w <= len && Same(out, w, f, w), "0x8A does not round-trip");
  }
  NodeIdentification ni;
  if (ParseNodeIdentification(f, len, &ni) == Status::kOk) {
    Check(std::memchr(ni.node_identifier, 0, sizeof ni.node_identifier) != nullptr, "0x95 NI not terminated");
    Check(BuildNodeIdentification(ni, out, sizeof out, &w) == Status::kOk && w <= len && Same(out, w, f, w),
          "0x95 does not round-trip");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FrameDecoder decoder(kMode);
  uint32_t frames = 0;
  for (size_t i = 0; i < size; ++i) {
    if (decoder.Feed(data[i]) != DecodeEvent::kFrame) continue;
    ++frames;
    const size_t len = decoder.frame_length();
    Check(len >= 1 && len <= kMaxFrameData, "frame length " + std::to_string(len) + " outside [1, kMaxFrameData]");
    uint8_t frame[kMaxFrameData];
    std::memcpy(frame, decoder.frame_data(), len);
    CheckRoundTrip(ApiMode::kUnescaped, frame, len);
    CheckRoundTrip(ApiMode::kEscaped, frame, len);
    CheckParsers(frame, len);
  }
  Check(decoder.counters().frames_ok == frames, "frames_ok differs from the frames delivered");

  if (kMode == ApiMode::kEscaped) {
    // A Modem Status "joined network" after whatever came before: mode 2 must deliver it.
    static const uint8_t kFrame[] = {0x8A, 0x02};
    uint8_t wire[kMaxWireFrame];
    const size_t n = EncodeFrame(kMode, kFrame, sizeof kFrame, wire, sizeof wire);
    bool delivered = false;
    for (size_t i = 0; i < n; ++i) {
      if (decoder.Feed(wire[i]) == DecodeEvent::kFrame && i + 1 == n) {
        delivered = Same(decoder.frame_data(), decoder.frame_length(), kFrame, sizeof kFrame);
      }
    }
    Check(delivered, "mode 2: a valid frame after the input was not delivered");
  }
  return 0;
}
