#include "firmware/report_queue.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw::firmware;

namespace {
QueuedRecord Rec(uint32_t seq, bool heartbeat) {
  QueuedRecord q;
  q.record.seq = seq;
  q.heartbeat = heartbeat;
  return q;
}
}  // namespace

TEST_GROUP(ReportQueue) {
  ReportQueue q;
};

TEST(ReportQueue, HeartbeatsGoBeforeSteps) {
  for (uint32_t i = 0; i < kQueueCapacity; ++i) CHECK(q.Push(Rec(i, i % 2 == 0)));
  CHECK(q.full());
  CHECK_FALSE(q.Push(Rec(1000, false)));  // evicts heartbeat 0
  LONGS_EQUAL(1, q.dropped_heartbeats());
  CHECK_FALSE(q.Ack(0));
  CHECK(q.Ack(1000));
  // Fill with steps only: a new heartbeat is dropped itself, a new step evicts the oldest step.
  ReportQueue steps;
  for (uint32_t i = 0; i < kQueueCapacity; ++i) steps.Push(Rec(i, false));
  CHECK_FALSE(steps.Push(Rec(500, true)));
  LONGS_EQUAL(1, steps.dropped_heartbeats());
  LONGS_EQUAL(kQueueCapacity, steps.size());
  CHECK_FALSE(steps.Push(Rec(501, false)));
  LONGS_EQUAL(1, steps.dropped_steps());
  CHECK_FALSE(steps.Ack(0));
  CHECK(steps.Ack(501));
  LONGS_EQUAL(2, steps.dropped_total());
}

TEST(ReportQueue, DueRespectsRetryTimesOldestFirst) {
  QueuedRecord a = Rec(1, false), b = Rec(2, false), c = Rec(3, true);
  a.next_try_s = 100;
  b.next_try_s = 50;
  c.next_try_s = 10;
  q.Push(a);
  q.Push(b);
  q.Push(c);
  size_t idx[4];
  LONGS_EQUAL(2, q.Due(60, idx, 4));
  LONGS_EQUAL(2, q.at(idx[0]).record.seq);
  LONGS_EQUAL(10, q.NextDue());
  LONGS_EQUAL(1, q.Due(200, idx, 1));
}
