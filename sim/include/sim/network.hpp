#pragma once
/// The virtual XBee network between the sensor boards and the coordinator: each transmission
/// attempt is lost with probability `loss` (the sender's radio then reports a delivery failure),
/// and a packet that gets through arrives after a random latency, sometimes twice (`dup`: a
/// retried MAC frame whose ack was lost). Deterministic for a seed. Times are virtual seconds.
#include <cstddef>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

namespace lw::sim {

struct NetworkParams {
  double loss = 0;          ///< probability that one transmission attempt is lost (0..1)
  double dup = 0;           ///< probability that a delivered packet is delivered twice (0..1)
  double latency_s = 0.05;  ///< mean one-way latency; each packet takes 0.5x..1.5x of it
  uint64_t seed = 1;
};

struct Packet {
  double at = 0;  ///< virtual time of arrival
  uint64_t src64 = 0;
  uint64_t dst64 = 0;
  std::vector<uint8_t> payload;
  uint64_t order = 0;  ///< tie-break: packets arriving at the same time keep their sending order
};

struct NetworkCounters {
  uint64_t attempts = 0;    ///< transmission attempts
  uint64_t lost = 0;        ///< attempts lost
  uint64_t duplicated = 0;  ///< packets delivered a second time
  uint64_t delivered = 0;   ///< arrivals (duplicates included)
};

class VirtualNetwork {
 public:
  explicit VirtualNetwork(const NetworkParams& params);

  /// The fate of one transmission attempt: true when it is lost.
  bool DrawLoss();
  /// Carries a packet that got through: it arrives after a random latency, sometimes twice.
  void Schedule(double now, uint64_t src64, uint64_t dst64, const uint8_t* payload, size_t len);
  /// DrawLoss, then Schedule when not lost; returns true when the packet got through.
  bool Send(double now, uint64_t src64, uint64_t dst64, const uint8_t* payload, size_t len);

  /// Arrival time of the next packet in flight (+infinity when none).
  double NextArrival() const;
  /// Removes and returns the packets that have arrived by `t`, in arrival order.
  std::vector<Packet> TakeArrived(double t);
  size_t in_flight() const { return in_flight_.size(); }
  const NetworkCounters& counters() const { return counters_; }
  const NetworkParams& params() const { return params_; }

 private:
  double Latency();
  NetworkParams params_;
  std::mt19937_64 rng_;
  std::uniform_real_distribution<double> uniform_{0.0, 1.0};
  std::vector<Packet> in_flight_;  // min-heap on (at, order)
  uint64_t next_order_ = 0;
  NetworkCounters counters_;
};

}  // namespace lw::sim
