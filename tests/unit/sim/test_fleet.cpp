// The virtual site without I/O: boards running the real firmware, driven by a truth, over the
// virtual network, with the test playing the gateway on the coordinator's serial side.
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "core/reconstruction.hpp"
#include "protocol/frame_decoder.hpp"
#include "protocol/sensor_payload.hpp"
#include "protocol/xbee_api.hpp"
#include "sim/campaign.hpp"
#include "sim/fleet.hpp"
#include "sim/truth.hpp"
#include "support/temp_directory.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw;
namespace pr = lw::protocol;

namespace {

sim::CampaignSpec SmallSpec(double days) {
  sim::CampaignSpec s;
  s.n_theta = 24;
  s.n_z = 12;
  s.days = days;
  s.reference_day = days;
  s.reference_wear_mm = 40;  // a fast campaign: many loops break in a few days
  s.write_scan = false;
  return s;
}

// Plays the gateway on the coordinator's serial side: acks every record of every 0x90 frame with
// a 0x10 (frame id set) and notes what it saw.
struct TestGateway {
  explicit TestGateway(pr::ApiMode m) : decoder(m), mode(m) {}
  pr::FrameDecoder decoder;
  pr::ApiMode mode;
  std::map<std::pair<std::string, uint32_t>, double> thickness;  // (sensor, seq) -> mm
  size_t frames = 0, status_ok = 0, status_failed = 0, acks_sent = 0;
  uint8_t frame_id = 0;

  void Serve(sim::Fleet& fleet) {
    const std::vector<uint8_t> bytes = fleet.TakeSerialOutput();
    std::vector<uint8_t> reply;
    for (uint8_t b : bytes) {
      if (decoder.Feed(b) != pr::DecodeEvent::kFrame) continue;
      pr::TransmitStatus st;
      if (pr::ParseTransmitStatus(decoder.frame_data(), decoder.frame_length(), &st) == pr::Status::kOk) {
        (st.delivery_status == 0 ? status_ok : status_failed)++;
        continue;
      }
      pr::ReceivePacket rx;
      CHECK(pr::ParseReceivePacket(decoder.frame_data(), decoder.frame_length(), &rx) == pr::Status::kOk);
      ++frames;
      pr::ReadingsHeader h;
      pr::SensorRecord recs[8];
      size_t n = 0;
      CHECK(pr::DecodeReadings(rx.payload, rx.payload_len, &h, recs, 8, &n) == pr::PayloadStatus::kOk);
      pr::Ack ack;
      ack.sensor_id = h.sensor_id;
      for (size_t i = 0; i < n; ++i) {
        thickness[{std::to_string(h.sensor_id), recs[i].seq}] = recs[i].thickness_dmm / 10.0;
        ack.seqs[ack.count++] = recs[i].seq;
      }
      uint8_t payload[pr::kMaxRfPayload];
      size_t plen = 0;
      CHECK(pr::EncodeAck(ack, payload, sizeof payload, &plen) == pr::PayloadStatus::kOk);
      pr::TransmitRequest req;
      frame_id = pr::NextFrameId(frame_id);
      req.frame_id = frame_id;
      req.dest64 = rx.src64;
      req.payload = payload;
      req.payload_len = plen;
      uint8_t wire[pr::kMaxWireFrame];
      const size_t w = pr::EncodeTransmitRequest(mode, req, wire, sizeof wire);
      CHECK(w > 0);
      reply.insert(reply.end(), wire, wire + w);
      ++acks_sent;
    }
    if (!reply.empty()) fleet.OnSerialInput(reply.data(), reply.size());
  }
};

// Runs the fleet to `days` (then drains), the test gateway answering after every event.
void RunFleet(sim::Fleet& fleet, TestGateway& gw, double days) {
  const double end = static_cast<double>(fleet.start_s()) + days * 86400.0;
  while (fleet.NextEventTime() <= end) {
    fleet.AdvanceTo(fleet.NextEventTime());
    gw.Serve(fleet);
  }
  fleet.AdvanceTo(end);
  for (int guard = 0; guard < 100000 && (fleet.queued_records() > 0 || fleet.in_flight() > 0); ++guard) {
    const double t = fleet.NextEventTime(false);
    if (!std::isfinite(t) || t > end + 2 * 86400.0) break;
    fleet.AdvanceTo(t, false);
    gw.Serve(fleet);
  }
}

sim::FleetOptions Options(double loss, double dup, uint64_t seed) {
  sim::FleetOptions o;
  o.network = {.loss = loss, .dup = dup, .latency_s = 0.05, .seed = seed};
  o.serial_mode = pr::ApiMode::kEscaped;
  return o;
}

}  // namespace

TEST_GROUP(SimFleet){};

TEST(SimFleet, BoardsReportTheTruthsLadderMonotonicallyAndEveryReadingReachesTheGateway) {
  const sim::CampaignTruth truth(sim::GenerateCampaign(SmallSpec(6), 4));
  const core::CrusherConfig& crusher = truth.campaign().crusher();
  sim::Fleet fleet(crusher, truth, Options(0.2, 0.05, 1));
  TestGateway gw(pr::ApiMode::kEscaped);
  RunFleet(fleet, gw, 6);

  const auto& ledger = fleet.ledger();
  CHECK(ledger.size() > 10 * 6 * 4);  // at least the 6-hourly heartbeats
  std::map<std::string, const sim::LedgerEntry*> last;
  std::map<std::string, size_t> index;
  for (size_t i = 0; i < crusher.sensors.size(); ++i) index[crusher.sensors[i].id] = i;
  std::set<std::string> wore;
  for (const sim::LedgerEntry& e : ledger) {
    // The reading is the ladder's lower bound of the true thickness at the sample time.
    const double day = static_cast<double>(e.time_s - fleet.start_s()) / 86400.0;
    const double true_mm = truth.ThicknessMm(index.at(e.sensor_id), day);
    CHECK_TEXT(e.thickness_mm <= true_mm + 1e-9 && e.thickness_mm > true_mm - 1.0, e.sensor_id.c_str());
    auto it = last.find(e.sensor_id);
    if (it != last.end()) {
      CHECK(e.seq > it->second->seq);
      CHECK(e.time_s >= it->second->time_s);
      CHECK(e.thickness_mm <= it->second->thickness_mm);  // wear never heals
      if (e.thickness_mm < it->second->thickness_mm) wore.insert(e.sensor_id);
    }
    last[e.sensor_id] = &e;
  }
  LONGS_EQUAL(crusher.sensors.size(), wore.size());
  // Through 20 % loss and duplicates, every reading reached the gateway with its thickness, and
  // every board saw all of its records acked.
  for (const sim::LedgerEntry& e : ledger) {
    auto it = gw.thickness.find({e.sensor_id, e.seq});
    CHECK_TEXT(it != gw.thickness.end(), (e.sensor_id + "/" + std::to_string(e.seq)).c_str());
    if (it != gw.thickness.end()) DOUBLES_EQUAL(e.thickness_mm, it->second, 1e-9);
  }
  LONGS_EQUAL(0, fleet.queued_records());
  LONGS_EQUAL(ledger.size(), fleet.counters().readings_acked);
  LONGS_EQUAL(0, fleet.unacked_serial_records());
  CHECK(fleet.network_counters().lost > 0);
  CHECK(fleet.network_counters().duplicated > 0);
  CHECK(gw.frames > fleet.counters().frames_to_gateway / 2);
  // Every ack request was answered with a transmit status; some acks were lost on the air.
  LONGS_EQUAL(gw.acks_sent, gw.status_ok + gw.status_failed);
  LONGS_EQUAL(fleet.counters().acks_lost, gw.status_failed);
  CHECK(gw.status_failed > 0);
}

TEST(SimFleet, SameSeedSameRunOtherSeedOtherRadioFate) {
  const sim::CampaignTruth truth(sim::GenerateCampaign(SmallSpec(2), 4));
  const auto run = [&](uint64_t seed) {
    sim::Fleet fleet(truth.campaign().crusher(), truth, Options(0.3, 0.1, seed));
    TestGateway gw(pr::ApiMode::kEscaped);
    RunFleet(fleet, gw, 2);
    std::vector<std::string> out;
    for (const auto& e : fleet.ledger()) {
      out.push_back(e.sensor_id + "/" + std::to_string(e.seq) + "/" + std::to_string(e.time_s) + "/" +
                    std::to_string(e.thickness_mm));
    }
    out.push_back(std::to_string(fleet.network_counters().lost) + "/" + std::to_string(fleet.network_counters().duplicated) +
                  "/" + std::to_string(fleet.counters().frames_to_gateway));
    return out;
  };
  const auto a = run(5), b = run(5), c = run(6);
  CHECK(a == b);
  CHECK(a.back() != c.back());
}

TEST(SimFleet, WithoutAGatewayNothingIsAckedAndTheBoardsKeepTheirRecords) {
  const sim::CampaignTruth truth(sim::GenerateCampaign(SmallSpec(1), 4));
  sim::Fleet fleet(truth.campaign().crusher(), truth, Options(0, 0, 1));
  // Half a day of this 40 mm-a-day campaign: ~20 steps a board, within the firmware's queue
  // (kQueueCapacity 32, sized for real wear rates; a whole day here would overflow it).
  fleet.AdvanceTo(static_cast<double>(fleet.start_s()) + 43200.0);
  CHECK(fleet.counters().frames_to_gateway > 0);
  LONGS_EQUAL(0, fleet.counters().readings_acked);
  LONGS_EQUAL(fleet.ledger().size(), fleet.queued_records());
  CHECK(fleet.unacked_serial_records() > 0);
}

TEST(SimFleet, SensorAddressesAndIds) {
  core::SensorInfo s;
  s.id = "1001";
  CHECK(sim::SensorAddress(s) == 0x0013A20000001001ull);
  s.address = 0x0013A200DEADBEEFull;
  CHECK(sim::SensorAddress(s) == 0x0013A200DEADBEEFull);
  LONGS_EQUAL(1001, sim::FirmwareSensorId("1001"));
  CHECK_THROWS(std::invalid_argument, sim::FirmwareSensorId("LUP-1"));
  CHECK_THROWS(std::invalid_argument, sim::FirmwareSensorId("4294967296"));
}

TEST(SimFleet, MapTruthWearsInProportionToTheMapAndCrusherFoldersChooseTheirTruth) {
  const sim::Campaign c = sim::GenerateCampaign(SmallSpec(3), 4);
  const lw::test::TempDirectory tmp("lw-sim-fleet");
  const std::filesystem::path& dir = tmp.path();
  c.WriteBundle(dir / "gen");
  const sim::CrusherFolder generated = sim::LoadCrusherFolder(dir / "gen");
  const auto* ct = dynamic_cast<const sim::CampaignTruth*>(generated.truth.get());
  CHECK(ct != nullptr);
  if (ct) DOUBLES_EQUAL(c.TrueSensorThickness(3, 2.5), ct->ThicknessMm(3, 2.5), 1e-9);

  // Without the generator's marker: the map model.
  std::filesystem::copy(dir / "gen", dir / "plain", std::filesystem::copy_options::recursive);
  std::filesystem::remove(dir / "plain" / sim::kCampaignMarker);
  const sim::CrusherFolder plain = sim::LoadCrusherFolder(dir / "plain");
  const auto* mt = dynamic_cast<const sim::MapTruth*>(plain.truth.get());
  CHECK(mt != nullptr);
  if (mt) {
    const core::CrusherConfig& cc = plain.crusher;
    const Eigen::VectorXd intensity = core::IntensityAtSensors(cc, c.map());
    Eigen::Index top = 0;
    intensity.maxCoeff(&top);
    // The fastest sensor has worn 94 % of (new - min) at day 95; the others in proportion.
    DOUBLES_EQUAL(cc.thickness_new_mm - 0.94 * (cc.thickness_new_mm - cc.thickness_min_mm),
                  mt->ThicknessMm(static_cast<size_t>(top), 95), 1e-6);
    for (size_t i = 0; i < cc.sensors.size(); ++i) {
      DOUBLES_EQUAL(intensity[static_cast<Eigen::Index>(i)] / intensity[top],
                    mt->rate_mm_per_day(i) / mt->rate_mm_per_day(static_cast<size_t>(top)), 1e-9);
      CHECK(mt->ThicknessMm(i, 10) <= mt->ThicknessMm(i, 5));
    }
  }
  CHECK_THROWS(std::runtime_error, sim::LoadCrusherFolder(dir / "missing"));
}

// The virtual radios as Digi's modules are: the coordinator answers the gateway's AT NP / EE, and
// every radio refuses a frame above the unfragmented payload they imply (0x74), so an oversize
// frame from the firmware or the gateway is lost in any run through the sim, never fragmented.
// With NP 49 (APS security) every reading still reaches the gateway.
TEST(SimFleet, TheVirtualRadiosAnswerNpAndRefuseAFrameAboveIt) {
  const sim::CampaignTruth truth(sim::GenerateCampaign(SmallSpec(3), 4));
  sim::FleetOptions o = Options(0.1, 0, 1);
  o.radio_np = 49;
  o.radio_ee = 1;
  sim::Fleet fleet(truth.campaign().crusher(), truth, o);
  pr::FrameDecoder dec(pr::ApiMode::kEscaped);
  const auto take = [&](uint8_t type) {
    std::vector<std::vector<uint8_t>> frames;
    for (uint8_t b : fleet.TakeSerialOutput()) {
      if (dec.Feed(b) == pr::DecodeEvent::kFrame && dec.frame_type() == type)
        frames.emplace_back(dec.frame_data(), dec.frame_data() + dec.frame_length());
    }
    return frames;
  };
  pr::AtCommand np;
  np.frame_id = 5;
  np.command[0] = 'N';
  np.command[1] = 'P';
  uint8_t wire[pr::kMaxWireFrame];
  fleet.OnSerialInput(wire, pr::EncodeAtCommand(pr::ApiMode::kEscaped, np, wire, sizeof wire));
  const auto answers = take(0x88);
  LONGS_EQUAL(1, answers.size());
  pr::AtCommandResponse rsp;
  CHECK(pr::ParseAtCommandResponse(answers[0].data(), answers[0].size(), &rsp) == pr::Status::kOk);
  uint64_t v = 0;
  CHECK(rsp.Value(&v));
  LONGS_EQUAL(49, v);
  // An ack sized for 84 bytes (18 seqs, 81 bytes) is refused.
  pr::Ack ack;
  ack.sensor_id = 1;
  ack.count = 18;
  uint8_t payload[pr::kMaxRfPayload];
  size_t plen = 0;
  CHECK(pr::EncodeAck(ack, payload, sizeof payload, &plen) == pr::PayloadStatus::kOk);
  pr::TransmitRequest req;
  req.frame_id = 6;
  req.dest64 = sim::SensorAddress(truth.campaign().crusher().sensors[0]);
  req.payload = payload;
  req.payload_len = plen;
  fleet.OnSerialInput(wire, pr::EncodeTransmitRequest(pr::ApiMode::kEscaped, req, wire, sizeof wire));
  const auto status = take(0x8B);
  LONGS_EQUAL(1, status.size());
  LONGS_EQUAL(0x74, status[0][5]);
  LONGS_EQUAL(1, fleet.counters().acks_too_large);

  TestGateway gw(pr::ApiMode::kEscaped);
  RunFleet(fleet, gw, 3);
  LONGS_EQUAL(0, fleet.counters().frames_too_large);
  for (const sim::LedgerEntry& e : fleet.ledger()) {
    CHECK_TEXT(gw.thickness.count({e.sensor_id, e.seq}) == 1, (e.sensor_id + "/" + std::to_string(e.seq)).c_str());
  }
  LONGS_EQUAL(0, fleet.queued_records());
}
