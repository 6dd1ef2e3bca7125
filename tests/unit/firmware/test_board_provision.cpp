// How an STM32 image applies its provisioning record at boot (firmware/board/stm32/provision.hpp),
// on a record in host memory: applied, absent, or refused with the Config left as it was.
#include <cstring>

#include "firmware/board/stm32/provision.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw;

namespace {
constexpr uint16_t kL431 = 0x0431, kF405 = 0x0405;
struct Flash {
  uint8_t bytes[protocol::kProvisionSize];
  uintptr_t address() const { return reinterpret_cast<uintptr_t>(bytes); }
};
Flash Record(uint16_t board, uint32_t sensor) {
  protocol::Provision p;
  p.board = board;
  p.sensor_id = sensor;
  p.api_mode = 1;
  p.ladder_loops = 48;
  Flash f;
  protocol::EncodeProvision(p, f.bytes);
  return f;
}
}  // namespace

TEST_GROUP(BoardProvision){};

TEST(BoardProvision, ARecordForThisBoardSetsSensorApiModeAndLadder) {
  const Flash f = Record(kL431, 2001);
  firmware::Config c;
  CHECK(board::ApplyProvision(kL431, f.address(), c) == board::ProvisionResult::kApplied);
  LONGS_EQUAL(2001, c.sensor_id);
  CHECK(c.api_mode == protocol::ApiMode::kUnescaped);
  LONGS_EQUAL(48, c.ladder_loops);
}

TEST(BoardProvision, ErasedFlashLeavesTheImagesDefaults) {
  Flash f;
  std::memset(f.bytes, 0xFF, sizeof f.bytes);
  firmware::Config c;
  const firmware::Config before = c;
  CHECK(board::ApplyProvision(kF405, f.address(), c) == board::ProvisionResult::kAbsent);
  LONGS_EQUAL(before.sensor_id, c.sensor_id);
  LONGS_EQUAL(before.ladder_loops, c.ladder_loops);
}

TEST(BoardProvision, AnotherBoardsOrACorruptedRecordIsRefusedAndChangesNothing) {
  Flash other = Record(kL431, 2001), bad = Record(kF405, 2001);
  bad.bytes[9] ^= 0x10;
  for (const Flash* f : {&other, &bad}) {
    firmware::Config c;
    const firmware::Config before = c;
    CHECK(board::ApplyProvision(kF405, f->address(), c) == board::ProvisionResult::kRefused);
    LONGS_EQUAL(before.sensor_id, c.sensor_id);
    LONGS_EQUAL(static_cast<int>(before.api_mode), static_cast<int>(c.api_mode));
    LONGS_EQUAL(before.ladder_loops, c.ladder_loops);
  }
}
