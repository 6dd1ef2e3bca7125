#pragma once
// Test helpers: hex vectors and feeding a decoder.
#include <cstdint>
#include <string>
#include <vector>

#include "protocol/frame_decoder.hpp"

namespace lw::protocol::test {

inline std::vector<uint8_t> Hex(const std::string& text) {
  std::vector<uint8_t> out;
  int nibble = -1;
  for (char c : text) {
    int v = -1;
    if (c >= '0' && c <= '9')
      v = c - '0';
    else if (c >= 'a' && c <= 'f')
      v = c - 'a' + 10;
    else if (c >= 'A' && c <= 'F')
      v = c - 'A' + 10;
    if (v < 0) continue;
    if (nibble < 0) {
      nibble = v;
    } else {
      out.push_back(static_cast<uint8_t>(nibble * 16 + v));
      nibble = -1;
    }
  }
  return out;
}

struct Decoded {
  std::vector<std::vector<uint8_t>> frames;
  std::vector<DecodeEvent> errors;
};

inline Decoded FeedAll(FrameDecoder& decoder, const std::vector<uint8_t>& bytes) {
  Decoded d;
  decoder.Feed(bytes.data(), bytes.size(), [&](DecodeEvent ev) {
    if (ev == DecodeEvent::kFrame) {
      d.frames.emplace_back(decoder.frame_data(), decoder.frame_data() + decoder.frame_length());
    } else {
      d.errors.push_back(ev);
    }
  });
  return d;
}

inline std::vector<uint8_t> Encode(ApiMode mode, const std::vector<uint8_t>& frame_data) {
  std::vector<uint8_t> out(kMaxWireFrame);
  const size_t n = EncodeFrame(mode, frame_data.data(), frame_data.size(), out.data(), out.size());
  out.resize(n);
  return out;
}

}  // namespace lw::protocol::test
