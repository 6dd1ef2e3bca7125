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
