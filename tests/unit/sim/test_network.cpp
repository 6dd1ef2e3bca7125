// The virtual XBee network: loss per attempt, duplicates, latency bounds, arrival order, seeds.
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "sim/network.hpp"

#include <CppUTest/TestHarness.h>

using lw::sim::NetworkParams;
using lw::sim::Packet;
using lw::sim::VirtualNetwork;

TEST_GROUP(VirtualNetwork){};

TEST(VirtualNetwork, LosslessNetworkDeliversEachPacketOnceWithinTheLatencyBand) {
  VirtualNetwork net({.loss = 0, .dup = 0, .latency_s = 0.2, .seed = 3});
  for (int i = 0; i < 500; ++i) {
    const uint8_t b[2] = {static_cast<uint8_t>(i & 0xFF), static_cast<uint8_t>(i >> 8)};
    CHECK(net.Send(i, 0x10, 0x20, b, 2));
  }
  const auto arrived = net.TakeArrived(1e12);
  LONGS_EQUAL(500, arrived.size());
  std::vector<int> seen(500, 0);
  double last = -1;
  for (const Packet& p : arrived) {
    const int i = p.payload.at(0) | (p.payload.at(1) << 8);
    CHECK(p.at >= last);  // arrival order
    last = p.at;
    const double latency = p.at - i;
    CHECK(latency >= 0.1 - 1e-9 && latency <= 0.3 + 1e-9);
    CHECK(p.src64 == 0x10 && p.dst64 == 0x20);
    ++seen.at(static_cast<size_t>(i));
  }
  for (int s : seen) LONGS_EQUAL(1, s);
  LONGS_EQUAL(0, net.in_flight());
}

TEST(VirtualNetwork, LossRateIsTheAttemptLossProbability) {
  VirtualNetwork net({.loss = 0.2, .dup = 0, .latency_s = 0.05, .seed = 11});
  int through = 0;
  for (int i = 0; i < 20000; ++i) {
    const uint8_t b = 1;
    if (net.Send(i, 1, 2, &b, 1)) ++through;
  }
  const auto arrived = net.TakeArrived(1e12);
  LONGS_EQUAL(through, arrived.size());
  const double lost = 1.0 - through / 20000.0;
  CHECK(lost > 0.18 && lost < 0.22);
  LONGS_EQUAL(20000, net.counters().attempts);
  LONGS_EQUAL(20000 - through, net.counters().lost);
}

TEST(VirtualNetwork, DuplicatesArriveTwiceTheSecondAfterTheFirst) {
  VirtualNetwork net({.loss = 0, .dup = 0.1, .latency_s = 0.05, .seed = 5});
  std::vector<double> first(5000, -1);
  int twice = 0;
  for (int i = 0; i < 5000; ++i) {
    const uint8_t b[2] = {static_cast<uint8_t>(i & 0xFF), static_cast<uint8_t>(i >> 8)};
    CHECK(net.Send(i * 10.0, 1, 2, b, 2));
  }
  for (const Packet& p : net.TakeArrived(1e12)) {
    const int i = p.payload[0] | (p.payload[1] << 8);
    if (first[static_cast<size_t>(i)] < 0) {
      first[static_cast<size_t>(i)] = p.at;
    } else {
      ++twice;
      CHECK(p.at >= first[static_cast<size_t>(i)]);
    }
  }
  for (double f : first) CHECK(f >= 0);
  LONGS_EQUAL(net.counters().duplicated, twice);
  CHECK(twice > 400 && twice < 600);
}

TEST(VirtualNetwork, OnlyWhatHasArrivedIsTaken) {
  VirtualNetwork net({.loss = 0, .dup = 0, .latency_s = 1.0, .seed = 1});
  const uint8_t b = 7;
  net.Send(100, 1, 2, &b, 1);
  CHECK(net.NextArrival() >= 100.5 && net.NextArrival() <= 101.5);
  CHECK(net.TakeArrived(100.4).empty());
  LONGS_EQUAL(1, net.TakeArrived(101.5).size());
  CHECK(net.TakeArrived(1e9).empty());
}

TEST(VirtualNetwork, SameSeedSameFateOtherSeedOther) {
  const auto fates = [](uint64_t seed) {
    VirtualNetwork net({.loss = 0.3, .dup = 0.2, .latency_s = 0.05, .seed = seed});
    std::vector<double> out;
    for (int i = 0; i < 300; ++i) {
      const uint8_t b = 0;
      out.push_back(net.Send(i, 1, 2, &b, 1) ? 1.0 : 0.0);
    }
    for (const Packet& p : net.TakeArrived(1e9)) out.push_back(p.at);
    return out;
  };
  CHECK(fates(9) == fates(9));
  CHECK(fates(9) != fates(10));
}

TEST(VirtualNetwork, BadParametersAreRefused) {
  CHECK_THROWS(std::invalid_argument, VirtualNetwork({.loss = 1.0}));
  CHECK_THROWS(std::invalid_argument, VirtualNetwork({.loss = -0.1}));
  CHECK_THROWS(std::invalid_argument, VirtualNetwork({.dup = 1.5}));
  CHECK_THROWS(std::invalid_argument, VirtualNetwork({.latency_s = -1}));
}
