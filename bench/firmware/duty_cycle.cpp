// Runs the real firmware App on the host HAL through a 95-day campaign and prints its duty cycle:
// wakes, ladder reads, radio frames and records per day. docs/firmware.md turns these counts into
// a battery-life estimate with datasheet currents.
#include <cmath>
#include <cstdio>
#include <cstring>

#include "firmware/app.hpp"
#include "hal/host/host_board.hpp"
#include "protocol/sensor_payload.hpp"

int main(int argc, char** argv) {
  if (argc > 1) {
    const bool help = argc == 2 && !std::strcmp(argv[1], "--help");
    std::fputs(
        "usage: lw_bench_duty_cycle\n"
        "Runs the real firmware App on the host HAL through a 95-day campaign and prints its duty cycle (wakes,\n"
        "ladder reads, radio frames and records per day); docs/firmware.md turns them into battery life.\n",
        help ? stdout : stderr);
    return help ? 0 : 2;
  }
  using namespace lw;
  firmware::Config config;
  hal::host::HostBoard hb(config.ladder_loops, 0x0013A20000001001ull, config.api_mode);
  hb.ladder.SetIntactCount(config.ladder_loops);
  uint32_t acked = 0;
  hb.radio.set_on_deliver([&](uint64_t, const uint8_t* p, size_t n) {
    protocol::ReadingsHeader h;
    protocol::SensorRecord recs[8];
    size_t count = 0;
    if (protocol::DecodeReadings(p, n, &h, recs, 8, &count) != protocol::PayloadStatus::kOk) return;
    protocol::Ack ack;
    ack.sensor_id = h.sensor_id;
    for (size_t i = 0; i < count; ++i) ack.seqs[ack.count++] = recs[i].seq;
    uint8_t buf[protocol::kMaxRfPayload];
    size_t len = 0;
    protocol::EncodeAck(ack, buf, sizeof buf, &len);
    hb.radio.Inject(buf, len);
    acked += static_cast<uint32_t>(count);
  });
  const hal::Board board = hb.board();
  firmware::App app(config, board);
  app.Init();
  const double days = 95.0;
  const uint32_t end = static_cast<uint32_t>(days * 86400);
  while (hb.rtc.now() < end) {
    // LDWN-like wear: 90 mm over the campaign, accelerating.
    const double f = hb.rtc.now() / static_cast<double>(end);
    hb.ladder.SetIntactCount(static_cast<uint8_t>(std::floor(100.0 - 90.0 * std::pow(f, 1.4))));
    app.RunOnce();
  }
  const auto& s = app.stats();
  std::printf("campaign: %.0f days, poll %u s, heartbeat %u s\n", days, config.poll_period_s, config.heartbeat_period_s);
  std::printf("wakes/day            %8.1f\n", s.wakes / days);
  std::printf("ladder reads/day     %8.1f (each = %u SPI transfers of %u bytes)\n",
              hb.ladder.transfers() / days / config.votes_per_poll, config.votes_per_poll, (config.ladder_loops + 7) / 8 + 1);
  std::printf("radio frames/day     %8.2f\n", s.frames_sent / days);
  std::printf("records/day          %8.2f (acked %u of %u queued)\n", s.records_queued / days, acked, s.records_queued);
  std::printf("flash saves          %8u (%.2f/day)\n", hb.flash.erases(), hb.flash.erases() / days);
  return 0;
}
