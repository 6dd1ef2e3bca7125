#pragma once
/// Building block for emulator images (freestanding): the ladder read over a second UART instead
/// of SPI, for machines with no shift registers to attach to their SPI bus (QEMU's mps2-an386 and
/// netduinoplus2). The host sends frames `0x55, n, n bytes` (the shift registers' image, loop i =
/// bit i%8 of byte i/8); Transfer() returns the latest image followed by the chain's 0xA5
/// signature byte, exactly what the real SPI chain returns, and fails (like an unpowered chain)
/// until a first image has arrived.
#include <cstddef>
#include <cstdint>

#include "hal/spi.hpp"
#include "hal/uart.hpp"

namespace lw::hal::port {

class UartLadder final : public Spi {
 public:
  explicit UartLadder(Uart& link) : link_(link) {}

 private:
  bool DoTransfer(const uint8_t* /*tx*/, uint8_t* rx, size_t len) override {
    Drain();
    for (size_t i = 0; i < len; ++i) {
      if (i < image_len_)
        rx[i] = image_[i];
      else if (i == image_len_)
        rx[i] = 0xA5;  // the chain's hard-wired signature register
      else
        rx[i] = 0;
    }
    return image_len_ > 0;
  }
  void Drain() {
    uint8_t b;
    while (link_.Read(&b, 1) == 1) {
      switch (parse_state_) {
        case 0:
          if (b == 0x55) parse_state_ = 1;
          break;
        case 1:
          parse_len_ = b;
          parse_pos_ = 0;
          parse_state_ = (b > 0 && b <= kMaxImage) ? 2 : 0;
          break;
        default:
          parse_[parse_pos_++] = b;
          if (parse_pos_ == parse_len_) {
            for (uint8_t i = 0; i < parse_len_; ++i) image_[i] = parse_[i];
            image_len_ = parse_len_;
            parse_state_ = 0;
          }
          break;
      }
    }
  }
  static constexpr uint8_t kMaxImage = 16;  // 128 loops
  Uart& link_;
  uint8_t image_[kMaxImage + 1] = {};
  uint8_t image_len_ = 0;
  uint8_t parse_[kMaxImage + 1] = {};
  uint8_t parse_state_ = 0;  // 0: wait 0x55, 1: length, 2: data
  uint8_t parse_len_ = 0;
  uint8_t parse_pos_ = 0;
};

}  // namespace lw::hal::port
