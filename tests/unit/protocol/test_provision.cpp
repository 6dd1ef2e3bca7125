// The provisioning record and the board table (protocol/provision.hpp): the record's bytes, its
// round trip, and every way a record is refused.
#include <cstring>

#include "protocol/provision.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw::protocol;

namespace {
Provision Sample() {
  Provision p;
  p.board = 0x0431;
  p.sensor_id = 123456;
  p.api_mode = 1;
  p.ladder_loops = 64;
  return p;
}
// Re-seals bytes 0..13 with their CRC, so a test reaches the checks after the CRC.
void Reseal(uint8_t r[kProvisionSize]) {
  const uint16_t crc = Crc16Ccitt(r, 14);
  r[14] = static_cast<uint8_t>(crc);
  r[15] = static_cast<uint8_t>(crc >> 8);
}
}  // namespace

TEST_GROUP(Provision){};

TEST(Provision, EncodesTheDocumentedLayout) {
  uint8_t r[kProvisionSize];
  EncodeProvision(Sample(), r);
  const uint8_t head[14] = {'L', 'W', 'P', 'R', 1, 1, 0x31, 0x04, 0x40, 0xE2, 0x01, 0x00, 64, 0xFF};
  MEMCMP_EQUAL(head, r, sizeof head);
  LONGS_EQUAL(Crc16Ccitt(r, 14), r[14] | (r[15] << 8));
}

TEST(Provision, DecodesWhatWasEncoded) {
  uint8_t r[kProvisionSize];
  EncodeProvision(Sample(), r);
  Provision p;
  CHECK(DecodeProvision(r, &p) == ProvisionStatus::kOk);
  LONGS_EQUAL(0x0431, p.board);
  LONGS_EQUAL(123456, p.sensor_id);
  LONGS_EQUAL(1, p.api_mode);
  LONGS_EQUAL(64, p.ladder_loops);
}

TEST(Provision, ErasedOrBlankFlashIsMissing) {
  uint8_t r[kProvisionSize];
  Provision p;
  std::memset(r, 0xFF, sizeof r);
  CHECK(DecodeProvision(r, &p) == ProvisionStatus::kMissing);
  std::memset(r, 0x00, sizeof r);
  CHECK(DecodeProvision(r, &p) == ProvisionStatus::kMissing);
}

TEST(Provision, EveryCorruptedByteIsRefused) {
  uint8_t good[kProvisionSize];
  EncodeProvision(Sample(), good);
  for (size_t i = 0; i < kProvisionSize; ++i) {
    uint8_t r[kProvisionSize];
    std::memcpy(r, good, sizeof r);
    r[i] = static_cast<uint8_t>(r[i] ^ 0x01);
    Provision p;
    const ProvisionStatus s = DecodeProvision(r, &p);
    CHECK_TEXT(s == (i < 4 ? ProvisionStatus::kMissing : ProvisionStatus::kBadCrc), ("byte " + std::to_string(i)).c_str());
  }
}

TEST(Provision, AnotherVersionIsRefused) {
  uint8_t r[kProvisionSize];
  EncodeProvision(Sample(), r);
  r[4] = 2;
  Reseal(r);
  Provision p;
  CHECK(DecodeProvision(r, &p) == ProvisionStatus::kBadVersion);
}

TEST(Provision, ValuesOutOfRangeAreRefusedEvenWithAGoodCrc) {
  struct Case {
    size_t at;
    uint8_t value;
  };
  // api mode 0 and 3; 0 and 129 loops; sensor id 0 (its four bytes).
  const Case cases[] = {{5, 0}, {5, 3}, {12, 0}, {12, kMaxLadderLoops + 1}};
  for (const Case& c : cases) {
    uint8_t r[kProvisionSize];
    EncodeProvision(Sample(), r);
    r[c.at] = c.value;
    Reseal(r);
    Provision p;
    CHECK_TEXT(DecodeProvision(r, &p) == ProvisionStatus::kBadValue, ("byte " + std::to_string(c.at)).c_str());
  }
  uint8_t r[kProvisionSize];
  EncodeProvision(Sample(), r);
  std::memset(r + 8, 0, 4);
  Reseal(r);
  Provision p;
  CHECK(DecodeProvision(r, &p) == ProvisionStatus::kBadValue);
}

TEST(Provision, TheBoardTableKeepsImagesRecordsAndBoardsApart) {
  for (size_t i = 0; i < sizeof kBoards / sizeof kBoards[0]; ++i) {
    const BoardInfo& b = kBoards[i];
    CHECK_TEXT(b.flash_base + b.image_max <= b.provision_address, b.name);  // an image cannot reach its record
    POINTERS_EQUAL(&b, FindBoardById(b.id));
    for (size_t j = 0; j < i; ++j) {
      CHECK(kBoards[j].id != b.id);
      CHECK(std::strcmp(kBoards[j].name, b.name) != 0);
    }
  }
  POINTERS_EQUAL(nullptr, FindBoardById(0x0000));
}
