// mqtt::ConnectSchedule: when both MQTT links (re)connect and which session they ask for.
#include "mqtt/link.hpp"

#include <CppUTest/TestHarness.h>

using lw::mqtt::ConnectSchedule;
using lw::mqtt::LinkOptions;

namespace {
LinkOptions Options(bool clean_session) {
  LinkOptions o;
  o.reconnect_min_ms = 100;
  o.reconnect_max_ms = 450;
  o.clean_session = clean_session;
  return o;
}
}  // namespace

TEST_GROUP(ConnectSchedule){};

TEST(ConnectSchedule, TheFirstAttemptIsDueAtOnceAndFailuresBackOffDoublingUpToTheMaximum) {
  ConnectSchedule s(Options(true));
  CHECK(s.Due(0));
  LONGS_EQUAL(100, s.Failed(1000));
  CHECK_FALSE(s.Due(1099));
  CHECK(s.Due(1100));
  LONGS_EQUAL(200, s.Failed(1100));
  LONGS_EQUAL(400, s.Failed(1300));
  LONGS_EQUAL(450, s.Failed(1700));
  LONGS_EQUAL(450, s.Failed(2150));
}

TEST(ConnectSchedule, AConnectionStartsTheBackoffAgainAndALossWaitsIt) {
  ConnectSchedule s(Options(true));
  s.Failed(0);
  s.Failed(100);  // backoff now 400
  s.Connected(500);
  s.Lost(60'000);
  CHECK_FALSE(s.Due(60'099));
  CHECK(s.Due(60'100));
}

TEST(ConnectSchedule, APersistentSessionAsksForItselfUntilItsConnectionsKeepDroppingThenOnceForACleanOne) {
  ConnectSchedule s(Options(false));
  ConnectSchedule::Attempt a = s.Start();
  CHECK_FALSE(a.clean_session);
  CHECK(a.notice.empty());
  // Two connections lost within 5 s of being made, in a row.
  s.Connected(0);
  s.Lost(1000);
  CHECK_FALSE(s.Start().clean_session);
  s.Connected(2000);
  s.Lost(3000);
  a = s.Start();
  CHECK(a.clean_session);
  CHECK(a.notice.find("clean session") != std::string::npos);
  // Once: the next attempt asks for the persistent session again.
  CHECK_FALSE(s.Start().clean_session);
}

TEST(ConnectSchedule, AConnectionThatLastedIsNoFlap) {
  ConnectSchedule s(Options(false));
  s.Connected(0);
  s.Lost(1000);
  s.Connected(2000);
  s.Lost(60'000);  // lasted 58 s
  s.Connected(61'000);
  s.Lost(62'000);
  CHECK_FALSE(s.Start().clean_session);
}

TEST(ConnectSchedule, ACleanSessionLinkIsNeverReset) {
  ConnectSchedule s(Options(true));
  for (int i = 0; i < 5; ++i) {
    s.Connected(i * 10);
    s.Lost(i * 10 + 1);
  }
  const ConnectSchedule::Attempt a = s.Start();
  CHECK(a.clean_session);
  CHECK(a.notice.empty());
}
