// The sensor payload (protocol/sensor_payload.hpp): readings and ack messages from arbitrary bytes.
// Properties: a message that decodes re-encodes to exactly the same bytes (the format has one
// encoding per message, so the decoder accepts nothing the encoder would not write), and the
// decoders never write past the capacity they are given.
#include <cstring>
#include <string>

#include "fuzz_support.hpp"
#include "protocol/sensor_payload.hpp"

using namespace lw::protocol;
using lw::fuzz::Check;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  // The first byte sets the records capacity (the gateway uses 8); the rest is the payload.
  constexpr size_t kCap = 32;
  SensorRecord records[kCap + 1];
  const size_t cap = size ? 1 + data[0] % kCap : kCap;
  std::memset(static_cast<void*>(&records[cap]), 0xA5, sizeof(SensorRecord) * (kCap + 1 - cap));
  ReadingsHeader h;
  size_t count = 0;
  const uint8_t* p = size ? data + 1 : data;
  const size_t n = size ? size - 1 : 0;
  const PayloadStatus st = DecodeReadings(p, n, &h, records, cap, &count);
  Check(PayloadStatusName(st) != nullptr, "PayloadStatusName returned null");
  for (size_t i = cap; i <= kCap; ++i) {
    const auto* b = reinterpret_cast<const uint8_t*>(&records[i]);
    for (size_t k = 0; k < sizeof(SensorRecord); ++k) Check(b[k] == 0xA5, "DecodeReadings wrote past records_cap");
  }
  if (st == PayloadStatus::kOk) {
    Check(count >= 1 && count <= cap, "record count " + std::to_string(count) + " outside [1, cap]");
    uint8_t out[kMaxRfPayload + 64];
    size_t w = 0;
    const PayloadStatus e = EncodeReadings(h, records, count, out, sizeof out, &w);
    Check(e == PayloadStatus::kOk, std::string("a decoded readings message does not encode: ") + PayloadStatusName(e));
    Check(w == n && std::memcmp(out, p, n) == 0, "a decoded readings message re-encodes differently");
  }
  Ack ack;
  if (DecodeAck(p, n, &ack) == PayloadStatus::kOk) {
    Check(ack.count <= kMaxAckSeqs, "ack count above kMaxAckSeqs");
    uint8_t out[kMaxRfPayload + 64];
    size_t w = 0;
    Check(EncodeAck(ack, out, sizeof out, &w) == PayloadStatus::kOk, "a decoded ack does not encode");
    Check(w == n && std::memcmp(out, p, n) == 0, "a decoded ack re-encodes differently");
  }
  return 0;
}
