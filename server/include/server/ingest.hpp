#pragma once
/// Ingest: validate reading messages (MQTT or REST), commit them in one transaction, and say which
/// (sensor, seq) pairs the gateway may now drop (commit acknowledgements, docs/mqtt.md).
/// Bad messages are never dropped: they go to the `rejected` table with their reason, are counted
/// and logged, and are acknowledged once stored there so the gateway does not resend them forever.
#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "estimate/window.hpp"
#include "server/live_state.hpp"
#include "server/registry.hpp"
#include "server/store.hpp"

namespace lw::server {

/// Readings stored but not used for wear (estimate/window.hpp: the one rule).
using estimate::IsFaultReading;

/// A stored reading as the wear estimate reads it.
inline estimate::Point PointOf(const StoredReading& r) {
  estimate::Point p;
  p.seq = r.seq;
  p.time_s = r.time_s;
  p.thickness_mm = r.thickness_mm;
  p.loops_intact = r.loops_intact;
  p.flags = r.flags;
  return p;
}

/// Whether a stored reading measures this liner's wear (estimate::UsableForWear: not a fault, and
/// of this liner, not a previous one's; docs/server.md, Relining).
inline bool UsableForWear(const core::CrusherConfig& crusher, const StoredReading& r) {
  return estimate::UsableForWear(crusher, r.sensor, PointOf(r));
}

struct Incoming {
  std::string site;
  std::string crusher;
  std::string sensor;  ///< from the topic (empty for REST, then the payload's is used)
  std::string topic;   ///< for the rejected table and logs
  std::string payload;
};

/// Outcome of validating one message. `reading` is set when it is valid; otherwise `error` says
/// why. `sensor`/`seq` are set whenever the payload named them (so a rejection can be acked).
/// `held` (a kHeldReasons class) marks a message that may become valid later: it is neither stored
/// nor quarantined nor acknowledged, so its gateway keeps it in its spool and publishes it again.
struct Validation {
  std::optional<StoredReading> reading;
  std::string error;
  std::string sensor;
  std::optional<int64_t> seq;
  const char* held = nullptr;
};

/// How far after the server's clock a reading's `time` may be and still be stored: a clock ahead
/// of the server's by more than this holds its readings until the server's clock catches up (a
/// reading in the future would otherwise become its sensor's latest and hide the genuine ones).
inline constexpr int64_t kFutureSlackS = 300;

/// Validates a reading message: decoded by mqtt::DecodeReading (size, nesting, JSON object, the
/// required fields and their ranges), then checked against the registry: `sensor` matching the
/// topic's, crusher and sensor known, `time` ISO-8601, not before the liner's installation minus a
/// day and not more than a day after `now_s`, `thickness_mm` in 0..thickness_new + 1. Held, not
/// refused: an unknown crusher (its folder may not have loaded yet) and a `time` more than
/// kFutureSlackS after `now_s` (but within the day).
Validation ValidateReading(const Incoming& in, const Registry& registry, int64_t now_s);

/// What the gateway of `site` may drop: sent as mqtt::EncodeCommitAcks on the sensor's
/// `committed` topic (docs/mqtt.md).
struct Ack {
  std::string site;
  std::string crusher;
  std::string sensor;
  std::vector<int64_t> seqs;
};

struct IngestResult {
  size_t stored = 0;
  size_t duplicates = 0;
  size_t conflicts = 0;
  size_t rejected = 0;
  size_t held = 0;                          ///< neither stored nor quarantined nor acked (Validation::held)
  std::vector<Ack> acks;                    ///< grouped per (site, crusher, sensor), seqs ascending
  std::vector<StoredReading> new_readings;  ///< stored by this call (not duplicates)
  std::vector<std::string> log;             ///< one line per rejection or conflict
};

/// The reason classes of rejected records (the `reason` label of /metrics' rejected counter,
/// docs/server.md, *Metrics*): a fixed set, whatever the message names in detail.
/// "conflict" is the class of a conflicting reading's quarantined copy (not a rejection reason).
inline constexpr const char* kRejectionReasons[] = {"malformed", "sensor_mismatch", "unknown_sensor", "time",
                                                    "thickness", "foreign_site",    "internal"};

/// The reason classes of held records (the `reason` label of /metrics' held counter): a crusher no
/// folder of the server defines, a `time` more than kFutureSlackS ahead of the server's clock, a
/// crusher without "site" on a server whose other crushers name theirs.
inline constexpr const char* kHeldReasons[] = {"unknown_crusher", "future", "no_site"};

struct IngestCounters {
  int64_t stored = 0, duplicates = 0, conflicts = 0, rejected = 0, held = 0, batches = 0;
  std::map<std::string, int64_t> rejected_by_reason;  ///< kRejectionReasons -> count (only those seen)
  std::map<std::string, int64_t> held_by_reason;      ///< kHeldReasons -> count (only those seen)
};

/// Thread-safe: the MQTT loop and REST handlers both call Ingest(). A message that fails validation
/// (or whose validation throws) is quarantined on its own: it never fails the rest of the batch.
class Ingestor {
 public:
  /// `live` (optional) is told every reading committed, in the same critical section as the commit.
  /// `now_s` (validation's "now", unix seconds) is called by Ingest() on its caller's thread (the
  /// server's MQTT loop or an HTTP worker) with the ingestor's lock held: one call at a time.
  Ingestor(Store& store, const Registry& registry, std::function<int64_t()> now_s, LiveState* live = nullptr);
  /// Validates and commits `messages` in one transaction. A message carrying several records
  /// (docs/mqtt.md, *Batches*) counts as its records, each validated, stored, a duplicate or
  /// rejected, and acked on its own; a malformed batch is rejected whole (it names no seq to ack).
  /// Throws std::runtime_error on a database failure (then nothing is stored and nothing may be
  /// acked).
  IngestResult Ingest(std::vector<Incoming> messages);
  IngestCounters Counters() const;
  /// Validation's "now" (unix seconds), under the ingestor's lock as Ingest() calls it: the time
  /// after which nothing has been read yet (GET .../wear?at= refuses later times).
  int64_t NowS() const;
  /// The site `crusher` belongs to: crusher.json's "site", else (on a server none of whose
  /// crushers names a site) the first site a valid reading was heard from (kept in the database).
  /// Readings, acks and wear go only to this site's topics; a message for the crusher under any
  /// other site is quarantined and not acknowledged. On a server with named sites a crusher without
  /// "site" has none: its readings are held (reason no_site).
  std::optional<std::string> SiteOf(const std::string& crusher) const;
  /// What the operator must fix, found at construction: one line per crusher without "site" on a
  /// server with named sites.
  const std::vector<std::string>& Warnings() const { return warnings_; }
  /// Per crusher: stored/duplicates/rejected since start.
  IngestCounters CrusherCounters(const std::string& crusher) const;

 private:
  Store& store_;
  const Registry& registry_;
  LiveState* live_ = nullptr;
  std::function<int64_t()> now_s_;
  mutable std::mutex mutex_;
  IngestCounters totals_;
  std::map<std::string, IngestCounters> per_crusher_;
  /// The site rule (SiteOf) on a record CheckReading passed or refused: sets *foreign (and
  /// quarantines) under another site, holds it for a crusher without "site" on a named-sites
  /// server, and binds a crusher heard for the first time in `new_sites`.
  void CheckSite(const Incoming& in, Validation& v, bool* foreign, std::map<std::string, std::string>& new_sites) const;
  std::map<std::string, std::string> sites_;  ///< crusher -> its site
  bool named_sites_ = false;                  ///< some crusher.json names its "site"
  std::vector<std::string> warnings_;
};

}  // namespace lw::server
