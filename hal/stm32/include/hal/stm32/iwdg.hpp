#pragma once
/// Independent watchdog (same IWDG on STM32F4 and STM32L4), clocked by the ~32 kHz LSI. With the
/// /256 prescaler one count is 8 ms and the longest timeout 4095 counts, about 32.8 s: a longer
/// `timeout_s` is clamped there (`timeout_s()` says what was set). The IWDG runs in Stop mode
/// unless the L4's IWDG_STOP option bit freezes it (the F4 cannot freeze it), so a port whose sleep
/// is longer than that kicks it from its sleep loop on each wake-up (RtcWakeupClock) and the
/// watchdog guards the awake time and the sleep loop itself.
///
/// Under QEMU (netduinoplus2) the IWDG is not modelled: writes are ignored and SR reads 0, so
/// Start() returns at once and no reset ever comes.
#include <cstdint>

#include "hal/stm32/mmio.hpp"
#include "hal/stm32/regs.hpp"
#include "hal/watchdog.hpp"

namespace lw::hal::stm32 {

template <class Io = Mmio>
class Iwdg final : public Watchdog {
 public:
  static constexpr uint32_t kCountsPerSecond = 32000u / 256u;  // LSI nominal / prescaler 256
  static constexpr uint32_t kMaxReload = 0xFFF;
  /// The timeout in force, seconds (after clamping).
  uint32_t timeout_s() const { return reload_ / kCountsPerSecond; }

 private:
  void DoStart(uint32_t timeout_s) override {
    const uint64_t counts = static_cast<uint64_t>(timeout_s) * kCountsPerSecond;
    reload_ = counts > kMaxReload ? kMaxReload : (counts == 0 ? 1u : static_cast<uint32_t>(counts));
    Io::Write32(iwdg::kBase + iwdg::kKr, iwdg::kKeyStart);  // starts the LSI and the counter
    Io::Write32(iwdg::kBase + iwdg::kKr, iwdg::kKeyUnlock);
    (void)WaitClear<Io>(iwdg::kBase + iwdg::kSr, iwdg::kSrPvu | iwdg::kSrRvu);
    Io::Write32(iwdg::kBase + iwdg::kPr, 6);  // /256
    Io::Write32(iwdg::kBase + iwdg::kRlr, reload_);
    (void)WaitClear<Io>(iwdg::kBase + iwdg::kSr, iwdg::kSrPvu | iwdg::kSrRvu);
    Io::Write32(iwdg::kBase + iwdg::kKr, iwdg::kKeyReload);
  }
  void DoKick() override { Io::Write32(iwdg::kBase + iwdg::kKr, iwdg::kKeyReload); }
  uint32_t reload_ = kMaxReload;
};

}  // namespace lw::hal::stm32
