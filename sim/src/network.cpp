#include "sim/network.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace lw::sim {
namespace {
// std::push_heap builds a max-heap: "greater" puts the earliest arrival on top.
bool Later(const Packet& a, const Packet& b) {
  return a.at > b.at || (a.at == b.at && a.order > b.order);
}
}  // namespace

VirtualNetwork::VirtualNetwork(const NetworkParams& params) : params_(params), rng_(params.seed) {
  if (!(params.loss >= 0 && params.loss < 1))
    throw std::invalid_argument("loss must be in [0, 1), got " + std::to_string(params.loss));
  if (!(params.dup >= 0 && params.dup <= 1))
    throw std::invalid_argument("dup must be in [0, 1], got " + std::to_string(params.dup));
  if (!(params.latency_s >= 0 && params.latency_s < 3600)) {
    throw std::invalid_argument("latency must be 0..3600 s, got " + std::to_string(params.latency_s));
  }
}

bool VirtualNetwork::DrawLoss() {
  ++counters_.attempts;
  const bool lost = uniform_(rng_) < params_.loss;
  if (lost) ++counters_.lost;
  return lost;
}

double VirtualNetwork::Latency() {
  return params_.latency_s * (0.5 + uniform_(rng_));
}

void VirtualNetwork::Schedule(double now, uint64_t src64, uint64_t dst64, const uint8_t* payload, size_t len) {
  Packet p;
  p.src64 = src64;
  p.dst64 = dst64;
  p.payload.assign(payload, payload + len);
  p.at = now + Latency();
  const bool twice = uniform_(rng_) < params_.dup;
  const double second_at = p.at + Latency();
  p.order = next_order_++;
  in_flight_.push_back(p);
  std::push_heap(in_flight_.begin(), in_flight_.end(), Later);
  if (twice) {
    ++counters_.duplicated;
    p.at = second_at;
    p.order = next_order_++;
    in_flight_.push_back(std::move(p));
    std::push_heap(in_flight_.begin(), in_flight_.end(), Later);
  }
}

bool VirtualNetwork::Send(double now, uint64_t src64, uint64_t dst64, const uint8_t* payload, size_t len) {
  if (DrawLoss()) return false;
  Schedule(now, src64, dst64, payload, len);
  return true;
}

double VirtualNetwork::NextArrival() const {
  return in_flight_.empty() ? std::numeric_limits<double>::infinity() : in_flight_.front().at;
}

std::vector<Packet> VirtualNetwork::TakeArrived(double t) {
  std::vector<Packet> out;
  while (!in_flight_.empty() && in_flight_.front().at <= t) {
    std::pop_heap(in_flight_.begin(), in_flight_.end(), Later);
    out.push_back(std::move(in_flight_.back()));
    in_flight_.pop_back();
  }
  counters_.delivered += out.size();
  return out;
}

}  // namespace lw::sim
