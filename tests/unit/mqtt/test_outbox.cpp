// mqtt::Outbox: what a publisher refuses is kept in order and sent when it takes messages again.
#include "fakes/fake_publisher.hpp"
#include "mqtt/outbox.hpp"

#include <CppUTest/TestHarness.h>

using lw::mqtt::Outbox;
using lw::mqtt::OutMessage;

TEST_GROUP(Outbox){};

TEST(Outbox, AMessageThePublisherTakesIsSentAtOnce) {
  lw::test::FakePublisher p;
  Outbox box;
  box.Send(p, {"t/a", "1", 1, false});
  LONGS_EQUAL(1, p.sent.size());
  LONGS_EQUAL(0, box.size());
}

TEST(Outbox, RefusedMessagesAreKeptAndSentInOrderOnceThePublisherTakesThemAgain) {
  lw::test::FakePublisher p;
  Outbox box;
  p.refuse = true;  // e.g. Paho's in-flight window is full
  box.Send(p, {"t/a", "1", 1, false});
  box.Send(p, {"t/a", "2", 1, false});
  LONGS_EQUAL(0, p.sent.size());
  LONGS_EQUAL(2, box.size());
  LONGS_EQUAL(0, box.Flush(p));
  p.refuse = false;
  box.Send(p, {"t/a", "3", 1, false});  // not before the two that wait
  LONGS_EQUAL(0, p.sent.size());
  LONGS_EQUAL(3, box.Flush(p));
  LONGS_EQUAL(3, p.sent.size());
  CHECK_EQUAL("1", p.sent[0].payload);
  CHECK_EQUAL("2", p.sent[1].payload);
  CHECK_EQUAL("3", p.sent[2].payload);
  LONGS_EQUAL(0, box.size());
}

TEST(Outbox, BeyondItsCapacityTheOldestIsDroppedAndCounted) {
  lw::test::FakePublisher p;
  p.connected = false;
  Outbox box(2);
  for (const char* m : {"1", "2", "3"}) box.Send(p, {"t", m, 1, false});
  LONGS_EQUAL(2, box.size());
  LONGS_EQUAL(1, box.dropped());
  p.connected = true;
  box.Flush(p);
  CHECK_EQUAL("2", p.sent.at(0).payload);
  CHECK_EQUAL("3", p.sent.at(1).payload);
}
