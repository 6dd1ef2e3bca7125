#include "firmware/ladder.hpp"
#include "hal/host/host_board.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw::firmware;
using lw::hal::host::HostLadder;
using lw::hal::host::HostPin;

TEST_GROUP(Ladder) {
  HostLadder ladder{100};
  HostPin power;
};

TEST(Ladder, CleanWearGivesContiguousCount) {
  ladder.SetIntactCount(63);
  const LadderSample s = ReadLadder(ladder, power, 5, 100);
  CHECK(s.valid);
  LONGS_EQUAL(63, s.loops_intact);
  LONGS_EQUAL(0, s.flags);
  CHECK_FALSE(power.high());  // powered only while read
  LONGS_EQUAL(1, power.rising_edges());
  LONGS_EQUAL(5, ladder.transfers());
}

TEST(Ladder, FlickerAtTheFaceIsVotedAndFlagged) {
  ladder.SetIntactCount(40);
  ladder.SetFlickerLoop(40);
  const LadderSample s = ReadLadder(ladder, power, 5, 100);
  CHECK(s.valid);
  CHECK(s.loops_intact == 40 || s.loops_intact == 41);
  CHECK(s.flags & lw::protocol::kFlagFlicker);
}

TEST(Ladder, CrackBelowTheFaceIsNonContiguousNotWear) {
  ladder.SetIntactCount(70);
  ladder.SetLoop(12, false);
  const LadderSample s = ReadLadder(ladder, power, 3, 100);
  LONGS_EQUAL(70, s.loops_intact);
  CHECK(s.flags & lw::protocol::kFlagNonContiguous);
}

TEST(Ladder, AllOpenIsFlagged) {
  ladder.SetIntactCount(0);
  const LadderSample s = ReadLadder(ladder, power, 3, 100);
  CHECK(s.valid);
  LONGS_EQUAL(0, s.loops_intact);
  CHECK(s.flags & lw::protocol::kFlagAllOpen);
}

TEST(Ladder, StuckBusIsNotReadAsWear) {
  ladder.SetIntactCount(70);
  for (int stuck : {0x00, 0xFF}) {
    ladder.SetStuckByte(stuck);
    const LadderSample s = ReadLadder(ladder, power, 3, 100);
    CHECK_FALSE(s.valid);
    CHECK(s.flags & lw::protocol::kFlagSpiStuck);
  }
  ladder.SetStuckByte(-1);
  ladder.SetTransferFails(true);
  CHECK_FALSE(ReadLadder(ladder, power, 3, 100).valid);
}

TEST(Ladder, FailedReadsAmongTheVotesAreExcludedAndReported) {
  ladder.SetIntactCount(55);
  ladder.FailNextTransfers(2);  // 2 of 5 reads fail: the other 3 still give the thickness
  LadderSample s = ReadLadder(ladder, power, 5, 100);
  CHECK(s.valid);
  LONGS_EQUAL(55, s.loops_intact);
  CHECK(s.flags & lw::protocol::kFlagSpiStuck);
  CHECK_FALSE(s.flags & lw::protocol::kFlagFlicker);
  ladder.FailNextTransfers(5);  // all 5 fail: no thickness from this poll
  s = ReadLadder(ladder, power, 5, 100);
  CHECK_FALSE(s.valid);
}

TEST(Ladder, MajorityVoteDecidesEachLoop) {
  // Decode raw reads directly: loop 20 reads intact in 2 of 5 reads, loop 10 open in 1 of 5.
  uint8_t raw[kMaxVotes][lw::protocol::kMaxBitmapBytes + 1] = {};
  for (int v = 0; v < 5; ++v) {
    for (int i = 0; i < 20; ++i) raw[v][i / 8] = static_cast<uint8_t>(raw[v][i / 8] | (1u << (i % 8)));
    if (v < 2) raw[v][20 / 8] = static_cast<uint8_t>(raw[v][20 / 8] | (1u << (20 % 8)));
    if (v == 4) raw[v][10 / 8] = static_cast<uint8_t>(raw[v][10 / 8] & ~(1u << (10 % 8)));
    raw[v][(24 + 7) / 8] = kLadderSignature;
  }
  const LadderSample s = DecodeLadder(raw, 5, 24);
  CHECK(s.valid);
  LONGS_EQUAL(20, s.loops_intact);  // loop 20 outvoted, loop 10 kept
  CHECK(s.flags & lw::protocol::kFlagFlicker);
  CHECK_FALSE(s.flags & lw::protocol::kFlagNonContiguous);
}
