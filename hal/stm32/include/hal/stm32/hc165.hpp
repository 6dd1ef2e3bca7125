#pragma once
/// The ladder's shift-register chain on an STM32 SPI master: daisy-chained 74HC165-class
/// parallel-in/serial-out registers. Wiring: SPI SCK to every CLK, the first register's QH to MISO,
/// each register's SER to the next one's QH, the last register's SER tied low, CLK INH tied low,
/// SH/LD of all registers to one GPIO (the latch). MOSI is not connected.
///
/// Transfer(): SH/LD low loads every register's parallel inputs (asynchronously, while low); back
/// high, the chain shifts on each rising SCK edge. QH shows input H (D7) of the first register from
/// the load on, and each edge moves the next bit to QH, so with SPI mode 0 (sampling on the rising
/// edge, before the 74HC165's propagation delay moves QH) and MSB first, received byte i is
/// register i with input H in bit 7 and input A in bit 0: loop 8i + b on input b of register i,
/// the chain's last register the hard-wired 0xA5 signature. Bytes clocked beyond the chain read the
/// tied-low SER: 0x00, which fails the signature check.
///
/// `Layout` (f4::SpiLayout, l4::SpiLayout) holds the family difference: 8-bit frames are the F4's
/// reset configuration, while the L4 needs CR2.DS = 8 bits and FRXTH = 1 (else RXNE waits for 16
/// bits in the RX FIFO). DR is accessed as a byte on both (on the L4 a 16-bit access would clock
/// two frames). Every wait is bounded: a bus that never completes makes Transfer() return false.
#include <cstddef>
#include <cstdint>

#include "hal/spi.hpp"
#include "hal/stm32/gpio.hpp"
#include "hal/stm32/mmio.hpp"
#include "hal/stm32/regs.hpp"

namespace lw::hal::stm32 {

template <class Layout, class Io = Mmio>
class Hc165Chain final : public Spi {
 public:
  /// `spi`: the SPI peripheral base; `latch_port`/`latch_pin`: the SH/LD GPIO.
  Hc165Chain(uintptr_t spi, uintptr_t latch_port, uint32_t latch_pin)
      : spi_(spi), latch_port_(latch_port), latch_pin_(latch_pin) {}

  /// Master, mode 0, MSB first, software NSS, SCK = f_pclk / 2^(br + 1). The latch idles high
  /// (shift mode). The port enables the SPI and GPIO clocks and the SCK/MISO pins first.
  void Init(uint32_t br) {
    WritePin<Io>(latch_port_, latch_pin_, true);
    ConfigurePin<Io>(latch_port_, latch_pin_, gpio::Mode::kOutput);
    Io::Write32(spi_ + spi::kCr1, 0);
    Io::Write32(spi_ + spi::kCr2, Layout::kCr2);
    const uint32_t cr1 = spi::kCr1Mstr | spi::kCr1Ssm | spi::kCr1Ssi | ((br & 7u) << spi::kCr1BrShift);
    Io::Write32(spi_ + spi::kCr1, cr1);
    Io::Write32(spi_ + spi::kCr1, cr1 | spi::kCr1Spe);
  }

 private:
  bool DoTransfer(const uint8_t* tx, uint8_t* rx, size_t len) override {
    if ((Io::Read32(spi_ + spi::kCr1) & spi::kCr1Spe) == 0) return false;  // not initialised
    // Stale bytes (an earlier aborted transfer) would be read as this chain's first bytes.
    for (uint32_t i = 0; i < 8 && (Io::Read32(spi_ + spi::kSr) & spi::kSrRxne); ++i) (void)Io::Read8(spi_ + spi::kDr);
    Latch();
    for (size_t i = 0; i < len; ++i) {
      if (!WaitSet<Io>(spi_ + spi::kSr, spi::kSrTxe)) return false;
      Io::Write8(spi_ + spi::kDr, tx ? tx[i] : 0x00);
      if (!WaitSet<Io>(spi_ + spi::kSr, spi::kSrRxne)) return false;
      rx[i] = Io::Read8(spi_ + spi::kDr);
    }
    if (!WaitClear<Io>(spi_ + spi::kSr, spi::kSrBsy)) return false;
    return (Io::Read32(spi_ + spi::kSr) & (spi::kSrModf | spi::kSrOvr)) == 0;
  }

  /// SH/LD low for at least the 74HC165's load pulse width (100 ns at 2 V): eight GPIO register
  /// reads (two or more bus cycles each) take longer than that up to the L4's 80 MHz.
  void Latch() {
    WritePin<Io>(latch_port_, latch_pin_, false);
    for (int i = 0; i < 8; ++i) (void)Io::Read32(latch_port_ + gpio::kIdr);
    WritePin<Io>(latch_port_, latch_pin_, true);
  }

  uintptr_t spi_;
  uintptr_t latch_port_;
  uint32_t latch_pin_;
};

}  // namespace lw::hal::stm32
