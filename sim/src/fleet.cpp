#include "sim/fleet.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "firmware/app.hpp"
#include "hal/host/host_board.hpp"
#include "protocol/sensor_payload.hpp"
#include "protocol/xbee_api.hpp"

namespace lw::sim {
namespace {

void AppendFrame(protocol::ApiMode mode, const uint8_t* frame, size_t len, std::vector<uint8_t>* out) {
  uint8_t wire[protocol::kMaxWireFrame];
  const size_t n = protocol::EncodeFrame(mode, frame, len, wire, sizeof wire);
  out->insert(out->end(), wire, wire + n);
}

}  // namespace

uint32_t FirmwareSensorId(const std::string& id) {
  if (id.empty() || id.size() > 10 || id.find_first_not_of("0123456789") != std::string::npos ||
      std::stoull(id) > 0xFFFFFFFFull) {
    throw std::invalid_argument("sensor id '" + id + "' must be a whole number below 2^32 (the firmware reports a 32-bit id)");
  }
  return static_cast<uint32_t>(std::stoull(id));
}

uint64_t SensorAddress(const core::SensorInfo& sensor) {
  if (sensor.address) return *sensor.address;
  uint64_t low = 0;
  if (sensor.id.size() <= 8 && sensor.id.find_first_not_of("0123456789") == std::string::npos) {
    low = std::stoull(sensor.id, nullptr, 16);
  } else {
    low = FirmwareSensorId(sensor.id);
  }
  return 0x0013A20000000000ull | low;
}

struct Fleet::Board {
  Board(const firmware::Config& c, uint64_t address, VirtualNetwork& network)
      : host(c.ladder_loops, address, c.api_mode),
        hal{host.ladder, host.ladder_power, host.radio, host.adc, host.rtc, host.power, host.watchdog, host.flash},
        app(c, hal),
        config(c) {
    // The virtual network decides the fate of each transmission (local AT queries stay local).
    host.radio.set_link_check([&network] { return !network.DrawLoss(); });
  }
  hal::host::HostBoard host;
  hal::Board hal;
  firmware::App app;
  firmware::Config config;
  size_t index = 0;
  std::string id;
  uint16_t src16 = 0;
  uint32_t next_wake = 0;
  uint32_t next_ledger_seq = 0;
};

Fleet::Fleet(const core::CrusherConfig& crusher, const TruthModel& truth, const FleetOptions& options)
    : truth_(truth),
      options_(options),
      start_s_(crusher.installed_at.time_since_epoch().count()),
      now_(static_cast<double>(start_s_)),
      network_(options.network),
      serial_in_(options.serial_mode) {
  if (start_s_ < 0 || start_s_ > 0xFFFFFFFFll - 10ll * 365 * 86400) {
    throw std::invalid_argument("installed_at must lie between 1970 and 2096 (the boards' RTC counts 32-bit seconds)");
  }
  for (size_t i = 0; i < crusher.sensors.size(); ++i) {
    const core::SensorInfo& s = crusher.sensors[i];
    firmware::Config config = options.firmware;
    config.sensor_id = FirmwareSensorId(s.id);
    const double new_mm = s.thickness_new_mm > 0 ? s.thickness_new_mm : crusher.thickness_new_mm;
    // A 1 mm ladder of up to 100 loops whose top loop is the new wear face.
    const double loops = std::clamp(std::floor(new_mm * 10.0 / config.loop_pitch_dmm), 1.0, 100.0);
    config.ladder_loops = static_cast<uint8_t>(loops);
    config.base_offset_dmm = static_cast<uint16_t>(std::lround(new_mm * 10.0 - loops * config.loop_pitch_dmm));
    const firmware::ConfigError error = firmware::CheckConfig(config);
    if (error != firmware::ConfigError::kOk) {
      throw std::invalid_argument("sensor " + s.id + ": firmware config: " + firmware::ConfigErrorText(error));
    }
    const uint64_t address = SensorAddress(s);
    if (by_address_.count(address)) throw std::invalid_argument("sensor " + s.id + ": radio address used twice");
    auto b = std::make_unique<Board>(config, address, network_);
    b->index = i;
    b->id = s.id;
    b->src16 = static_cast<uint16_t>(0x1000 + i);
    const uint32_t boot =
        static_cast<uint32_t>(start_s_) +
        (crusher.sensors.size() > 1
             ? static_cast<uint32_t>(options.boot_spread_s * static_cast<double>(i) / static_cast<double>(crusher.sensors.size()))
             : 0u);
    b->host.rtc.Set(boot);
    b->host.ladder.SetIntactCount(config.ladder_loops);
    b->host.radio.set_np(options.radio_np);
    b->host.radio.set_ee(options.radio_ee);
    Board* raw = b.get();
    b->host.radio.set_on_deliver([this, raw](uint64_t src64, const uint8_t* payload, size_t len) {
      network_.Schedule(static_cast<double>(raw->host.rtc.now()), src64, protocol::kCoordinatorAddress64, payload, len);
    });
    b->app.Init();
    b->next_wake = boot;
    by_address_[address] = raw;
    boards_.push_back(std::move(b));
  }
}

Fleet::~Fleet() = default;

double Fleet::NextEventTime(bool sample) const {
  double t = network_.NextArrival();
  for (const auto& b : boards_) {
    if (sample || b->app.queue().size() > 0) t = std::min(t, static_cast<double>(b->next_wake));
  }
  return t;
}

void Fleet::WakeBoard(Board& b, uint32_t at) {
  b.host.rtc.Set(at);
  const double day = static_cast<double>(static_cast<int64_t>(at) - start_s_) / 86400.0;
  const double thickness_dmm = truth_.ThicknessMm(b.index, day) * 10.0;
  const double intact = std::floor((thickness_dmm - b.config.base_offset_dmm) / b.config.loop_pitch_dmm);
  b.host.ladder.SetIntactCount(static_cast<uint8_t>(std::clamp(intact, 0.0, static_cast<double>(b.config.ladder_loops))));
  b.next_wake = b.app.Step();
  if (b.next_wake <= at) b.next_wake = at + 1;
  // Every record the firmware queued during this wake, in seq order.
  std::vector<LedgerEntry> fresh;
  const firmware::ReportQueue& q = b.app.queue();
  for (size_t i = 0; i < q.size(); ++i) {
    const firmware::QueuedRecord& r = q.at(i);
    if (r.record.seq < b.next_ledger_seq) continue;
    fresh.push_back({b.id, r.record.seq, static_cast<int64_t>(r.sampled_at_s), r.record.thickness_dmm / 10.0});
  }
  std::sort(fresh.begin(), fresh.end(), [](const LedgerEntry& x, const LedgerEntry& y) { return x.seq < y.seq; });
  for (const LedgerEntry& e : fresh) {
    ledger_.push_back(e);
    b.next_ledger_seq = e.seq + 1;
  }
}

void Fleet::Arrive(const Packet& p) {
  if (p.dst64 != protocol::kCoordinatorAddress64) {
    auto it = by_address_.find(p.dst64);
    if (it != by_address_.end()) it->second->host.radio.Inject(p.payload.data(), p.payload.size());
    return;
  }
  auto it = by_address_.find(p.src64);
  const uint16_t src16 = it != by_address_.end() ? it->second->src16 : protocol::kUnknownAddress16;
  const protocol::ReceivePacket rx{p.src64, src16, 0x01 /* acknowledged */, p.payload.data(), p.payload.size()};
  uint8_t wire[protocol::kMaxWireFrame];
  const size_t n = protocol::EncodeReceivePacket(options_.serial_mode, rx, wire, sizeof wire);
  if (n == 0) return;
  serial_out_.insert(serial_out_.end(), wire, wire + n);
  ++counters_.frames_to_gateway;
  protocol::ReadingsHeader header;
  protocol::SensorRecord records[8];
  size_t count = 0;
  if (protocol::DecodeReadings(p.payload.data(), p.payload.size(), &header, records, 8, &count) == protocol::PayloadStatus::kOk) {
    for (size_t i = 0; i < count; ++i) unacked_.insert({header.sensor_id, records[i].seq});
  }
}

void Fleet::AdvanceTo(double t, bool sample) {
  for (;;) {
    const double arrival = network_.NextArrival();
    Board* next = nullptr;
    for (const auto& b : boards_) {
      if (!sample && b->app.queue().size() == 0) continue;
      if (!next || b->next_wake < next->next_wake) next = b.get();
    }
    const double wake = next ? static_cast<double>(next->next_wake) : std::numeric_limits<double>::infinity();
    const double at = std::min(arrival, wake);
    if (at > t) break;
    now_ = std::max(now_, at);
    if (arrival <= wake) {
      for (const Packet& p : network_.TakeArrived(arrival)) Arrive(p);
    } else {
      WakeBoard(*next, next->next_wake);
    }
  }
  now_ = std::max(now_, t);
}

std::vector<uint8_t> Fleet::TakeSerialOutput() {
  std::vector<uint8_t> out;
  out.swap(serial_out_);
  return out;
}

void Fleet::OnSerialInput(const uint8_t* data, size_t len) {
  serial_in_.Feed(data, len, [&](protocol::DecodeEvent event) {
    if (event != protocol::DecodeEvent::kFrame) return;
    protocol::TransmitRequest req;
    if (protocol::ParseTransmitRequest(serial_in_.frame_data(), serial_in_.frame_length(), &req) == protocol::Status::kOk) {
      OnGatewayTransmit(req);
      return;
    }
    protocol::AtCommand cmd;
    if (protocol::ParseAtCommand(serial_in_.frame_data(), serial_in_.frame_length(), &cmd) == protocol::Status::kOk) {
      AnswerAt(cmd);
      return;
    }
    ++counters_.serial_bad_frames;
  });
}

void Fleet::AnswerAt(const protocol::AtCommand& cmd) {
  ++counters_.at_queries;
  if (cmd.frame_id == 0) return;
  uint8_t frame[16];
  size_t n = 0;
  if (protocol::BuildRadioSettingsAnswer(cmd, options_.radio_np, options_.radio_ee, frame, sizeof frame, &n) ==
      protocol::Status::kOk) {
    AppendFrame(options_.serial_mode, frame, n, &serial_out_);
  }
}

void Fleet::OnGatewayTransmit(const protocol::TransmitRequest& req) {
  ++counters_.acks_from_gateway;
  const bool too_large = req.payload_len > protocol::RfPayloadLimit(options_.radio_np, options_.radio_ee);
  protocol::Ack ack;
  if (!too_large && protocol::DecodeAck(req.payload, req.payload_len, &ack) == protocol::PayloadStatus::kOk) {
    for (size_t k = 0; k < ack.count; ++k) unacked_.erase({ack.sensor_id, ack.seqs[k]});
  }
  bool delivered = false;
  auto it = by_address_.find(req.dest64);
  if (too_large) {
    ++counters_.acks_too_large;
  } else if (it != by_address_.end()) {
    delivered = network_.Send(now_, protocol::kCoordinatorAddress64, req.dest64, req.payload, req.payload_len);
    if (!delivered) ++counters_.acks_lost;
  } else {
    ++counters_.serial_bad_frames;
  }
  if (req.frame_id == 0) return;
  protocol::TransmitStatus st;
  st.frame_id = req.frame_id;
  st.dest16 = it != by_address_.end() ? it->second->src16 : protocol::kUnknownAddress16;
  st.delivery_status = delivered   ? uint8_t{0x00}
                       : too_large ? static_cast<uint8_t>(protocol::DeliveryStatus::kDataPayloadTooLarge)
                                   : static_cast<uint8_t>(protocol::DeliveryStatus::kNetworkAckFailure);
  uint8_t frame[16];
  size_t n = 0;
  if (protocol::BuildTransmitStatus(st, frame, sizeof frame, &n) == protocol::Status::kOk) {
    AppendFrame(options_.serial_mode, frame, n, &serial_out_);
  }
}

size_t Fleet::queued_records() const {
  size_t n = 0;
  for (const auto& b : boards_) n += b->app.queue().size();
  return n;
}

FleetCounters Fleet::counters() const {
  FleetCounters c = counters_;
  c.readings_produced = ledger_.size();
  c.readings_acked = 0;
  for (const auto& b : boards_) {
    c.readings_acked += b->app.stats().records_acked;
    c.frames_too_large += b->host.radio.refused_too_large();
  }
  return c;
}

}  // namespace lw::sim
