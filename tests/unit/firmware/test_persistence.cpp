#include "firmware/persistence.hpp"
#include "hal/host/host_board.hpp"

#include <CppUTest/TestHarness.h>

using namespace lw::firmware;
using lw::hal::host::HostFlash;

TEST_GROUP(Persistence){};

TEST(Persistence, FreshFlashHasNoState) {
  HostFlash flash(256, 2);
  StateStore store(flash, 0);
  PersistentState s;
  CHECK_FALSE(store.Load(&s));
}

TEST(Persistence, NewestGenerationWinsAcrossReopen) {
  HostFlash flash(256, 2);
  {
    StateStore store(flash, 0);
    PersistentState s;
    for (uint32_t i = 1; i <= 5; ++i) {
      s.seq_reserved_until = i * 64;
      CHECK(store.Save(&s));
    }
  }
  StateStore reopened(flash, 0);
  PersistentState s;
  CHECK(reopened.Load(&s));
  LONGS_EQUAL(5 * 64, s.seq_reserved_until);
  LONGS_EQUAL(5, s.generation);
}

// Power lost at every byte of a save (erase + program): the state afterwards is the old one or,
// when the save completed, the new one; never garbage, never older than before.
TEST(Persistence, PowerLossAtEveryByteOfAWriteRecovers) {
  HostFlash probe(256, 2);
  StateStore probe_store(probe, 0);
  PersistentState p;
  probe_store.Save(&p);
  const uint64_t before = probe.work_bytes();
  probe_store.Save(&p);
  const long bytes_per_save = static_cast<long>(probe.work_bytes() - before);
  CHECK(bytes_per_save > 256);

  for (long cut = 0; cut <= bytes_per_save; ++cut) {
    HostFlash flash(256, 2);
    PersistentState old_state;
    {
      StateStore store(flash, 0);
      old_state.seq_reserved_until = 128;
      old_state.reported_loops = 77;
      CHECK(store.Save(&old_state));
      old_state.seq_reserved_until = 192;
      old_state.reported_loops = 76;
      CHECK(store.Save(&old_state));
    }
    bool completed = false;
    {
      StateStore store(flash, 0);
      PersistentState loaded;
      CHECK(store.Load(&loaded));
      loaded.seq_reserved_until = 256;
      loaded.reported_loops = 75;
      flash.LosePowerAfter(cut);
      completed = store.Save(&loaded);
    }
    flash.PowerRestored();
    StateStore after(flash, 0);
    PersistentState got;
    CHECK(after.Load(&got));
    if (completed) {
      LONGS_EQUAL(256, got.seq_reserved_until);
      LONGS_EQUAL(75, got.reported_loops);
    } else {
      CHECK(got.seq_reserved_until == 192 || got.seq_reserved_until == 256);
      CHECK(got.reported_loops == 76 || got.reported_loops == 75);
      CHECK((got.seq_reserved_until == 256) == (got.reported_loops == 75));
    }
    // And the store keeps working after recovery.
    got.seq_reserved_until = 320;
    CHECK(after.Save(&got));
    StateStore again(flash, 0);
    PersistentState last;
    CHECK(again.Load(&last));
    LONGS_EQUAL(320, last.seq_reserved_until);
  }
}
