// EventBus: events in order per crusher; a lazily published event's data is built once, only when
// a reader takes it, and the same for every reader.
#include <chrono>
#include <string>

#include "server/events.hpp"

#include <CppUTest/TestHarness.h>  // last: its leak-detection macros clash with std headers

using namespace lw::server;

TEST_GROUP(Events){};

TEST(Events, ALazyEventIsBuiltOnceWhenFirstReadAndNeverWhenNobodyReads) {
  EventBus bus(3);
  int built = 0;
  const auto make = [&built](const std::string& data) {
    return [&built, data] {
      ++built;
      return data;
    };
  };
  bus.PublishLazy("c1", "reading", make("{\"seq\":1}"));
  bus.PublishLazy("c1", "reading", make("{\"seq\":2}"));
  LONGS_EQUAL(0, built);
  // Pushed out of the ring (capacity 3) before anyone read it: never built.
  bus.PublishLazy("c1", "reading", make("{\"seq\":3}"));
  bus.Publish("c2", "wear", "{}");
  bus.PublishLazy("c1", "reading", make("{\"seq\":4}"));
  LONGS_EQUAL(0, built);

  int64_t after = 0;
  std::vector<Event> got = bus.WaitAfter(&after, "c1", std::chrono::milliseconds(0));
  LONGS_EQUAL(2, got.size());
  STRCMP_EQUAL("{\"seq\":3}", got[0].data.c_str());
  STRCMP_EQUAL("{\"seq\":4}", got[1].data.c_str());
  LONGS_EQUAL(3, got[0].id);
  LONGS_EQUAL(5, after);
  LONGS_EQUAL(2, built);

  // A second reader (a reconnecting client with Last-Event-ID) gets the same data, not built again.
  int64_t from_start = 0;
  got = bus.WaitAfter(&from_start, "c1", std::chrono::milliseconds(0));
  LONGS_EQUAL(2, got.size());
  STRCMP_EQUAL("{\"seq\":4}", got[1].data.c_str());
  LONGS_EQUAL(2, built);
}
