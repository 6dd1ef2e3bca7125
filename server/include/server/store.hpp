#pragma once
/// The server's SQLite database: readings (unique on crusher + sensor + seq, so a redelivery is
/// harmless), quarantined messages that failed validation (kept, never dropped), and the latest
/// diagnosis per crusher. WAL journal, prepared statements, one transaction per batch.
///
/// Threads: a Store is one SQLite connection with its prepared statements, and is NOT safe to use
/// from two threads at once. Use each Store from one thread at a time: own it on one thread, or
/// share it through a LockedStore (below), or behind a lock of the object that owns it (Ingestor,
/// LiveState). Several Stores on the same file may be used at once from different threads (WAL:
/// readers and the writer do not block each other). In
/// linerwatch-server: one writing Store owned by the Ingestor (MQTT loop and REST posts, under its
/// lock), one LockedStore for the REST reads, one LockedStore for the diagnosis, and one Store
/// for LiveState's lazy loads (under its lock).
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace lw::server {

struct StoredReading {
  std::string crusher;
  std::string sensor;
  int64_t seq = 0;
  int64_t time_s = 0;  ///< unix seconds, when the sample was taken
  double thickness_mm = 0;
  int64_t loops_intact = 0;
  int64_t flags = 0;
  int64_t battery_mv = 0;
  int64_t received_s = 0;  ///< unix seconds, when the server first stored it
  std::string payload;     ///< the message as received (JSON)
};

struct Rejected {
  int64_t received_s = 0;
  std::string topic;
  std::string payload;
  std::string reason;
  std::string reason_class;  ///< its kRejectionReasons class, or "conflict": the unit of the table's fair share
};

enum class InsertOutcome {
  kStored,     ///< new
  kDuplicate,  ///< the same (crusher, sensor, seq) with the same content was already stored
  kConflict,   ///< the same key with different content: the first one is kept, this is logged
};

/// Caps on the `rejected` table: when a new row would exceed one, the oldest rows are deleted and
/// counted (RejectedEvicted). Payloads longer than max_payload_bytes are stored truncated.
struct RejectedLimits {
  int64_t max_rows = 100'000;
  int64_t max_bytes = 64LL << 20;
  size_t max_payload_bytes = 4096;
};

struct Page {
  std::vector<StoredReading> readings;
  std::optional<std::string> next_cursor;
};

/// The paging cursor of Store::Range: "t<time_s>s<seq>" of the last reading of a page.
std::string MakeCursor(int64_t time_s, int64_t seq);
/// Reads a cursor back; throws std::invalid_argument ("cursor '...' is not one this server issued").
void ParseCursor(const std::string& cursor, int64_t* time_s, int64_t* seq);

/// One liner campaign of a crusher (docs/campaigns.md): from its start (the liner's installation) to
/// its end (the reline that replaced it; none while it runs).
struct CampaignRecord {
  int64_t id = 0;  ///< the row's id; 0 before it is stored
  int64_t start_s = 0;
  std::optional<int64_t> end_s;
  double thickness_new_mm = 0;
  std::string sensors_json;         ///< the campaign's sensors: a JSON array of crusher.json sensor objects
  std::string final_scan;           ///< the liner's end-of-life scan (`x y z` text); empty: none
  std::string final_readings_json;  ///< a JSON array of each sensor's last reading of the liner; "[]" while it runs
  int64_t created_s = 0;            ///< when the server stored it
  /// A reline posted by mistake (docs/campaigns.md, *Voiding a reline*): when it was voided, by
  /// whom (the token's name) and why; the campaign it closed runs again. Kept, never counted.
  std::optional<int64_t> voided_s;
  std::string voided_by;
  std::string void_reason;
  std::string reline_scan;  ///< a voided reline's scan_xyz (the end-of-life scan it carried); empty: none
};

/// A closed-side setting measured on a crusher (docs/wear.md, *Setting*; POST .../setting/checks).
struct SettingCheckRecord {
  std::string crusher;
  int64_t time_s = 0;  ///< when it was measured
  double css_mm = 0;
  /// The concave's opening since installation estimated at time_s (the central estimate); none:
  /// not known (no sensor set a scale, or no reading of the liner up to then).
  std::optional<double> opening_mm;
  bool opening_supported = false;  ///< the discharge ring's band was within the thinnest-area target then
  std::string by;                  ///< the token's name
  std::string note;
  int64_t recorded_s = 0;  ///< when the server stored it
};

/// One alarm as stored (docs/alarms.md): one row per episode of a rule on its subject (a row, a
/// sensor, a gateway, the crusher), from its raise to its clear.
struct AlarmRecord {
  int64_t id = 0;  ///< 0 before it is first stored
  std::string crusher;
  std::string rule;     ///< core::AlarmRuleSpecs() name
  std::string subject;  ///< what it is about: a row name, a sensor id, a gateway id, or the crusher id
  std::string severity;
  std::string state;  ///< "active", "acknowledged" or "cleared"
  int64_t since_s = 0;
  std::string detail;               ///< one line a person can act on
  std::optional<double> value;      ///< the value that raised it, in the rule's unit
  std::optional<double> threshold;  ///< the rule's threshold when it was raised
  std::optional<int64_t> acknowledged_s;
  std::string acknowledged_by;  ///< the token's name ("anonymous" on an open API)
  std::optional<int64_t> cleared_s;
};

/// The audit trail of an alarm: raised, acknowledged (by whom), cleared; and rule changes (alarm 0).
struct AlarmAuditEntry {
  int64_t alarm = 0;
  int64_t time_s = 0;
  std::string action;  ///< "raised", "acknowledged", "cleared", "rules"
  std::string by;      ///< "server", or the token's name
  std::string detail;
};

/// One notification of an alarm event to one receiver (docs/alarms.md, *Notifications*): queued
/// with the event, retried until the receiver takes it, kept after with its state.
struct NotificationRecord {
  int64_t id = 0;
  int64_t audit = 0;    ///< the alarm_audit row of the event
  std::string channel;  ///< "webhook" or "email"
  std::string target;   ///< the webhook's URL, the e-mail's smtp_url
  std::string event;    ///< "raised", "acknowledged", "cleared"
  std::string body;     ///< what is sent (the webhook's JSON; the e-mail's JSON, written as text when sent)
  int64_t created_s = 0;
  std::string state;  ///< "pending", "delivered", "dropped" (its receiver is no longer configured)
  int64_t attempts = 0;
  int64_t next_attempt_s = 0;
  std::optional<int64_t> done_s;  ///< delivered or dropped at
  std::string last_error;
};

/// What Store::QueueNotifications stores for one event and receiver.
struct QueuedNotification {
  std::string channel, target, body;
};
/// The notifications of one alarm event (`alarm` as stored now, `event` its audit entry, `event_id` that entry's row id).
using NotificationMaker =
    std::function<std::vector<QueuedNotification>(const AlarmRecord& alarm, const AlarmAuditEntry& event, int64_t event_id)>;

class Store {
 public:
  /// Opens (creating if needed) the database. Throws std::runtime_error naming the file on failure
  /// (unreadable, not a database, newer schema).
  /// A new database file is created with mode 0600.
  explicit Store(const std::filesystem::path& path, RejectedLimits limits = {});
  /// Opens an existing database read-only, writing nothing, not even SQLite's -wal/-shm files (it
  /// is opened immutable: what the database file holds, without a -wal file left by a crash). For
  /// serving reads while the disk is full; every write throws.
  static std::unique_ptr<Store> OpenReadOnly(const std::filesystem::path& path);
  ~Store();
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  /// Stores `readings`, `rejected` (each once: a message already quarantined is not stored again)
  /// and new crusher -> site bindings in ONE transaction; on any error nothing is committed and
  /// std::runtime_error is thrown. Returns one outcome per reading, in order.
  std::vector<InsertOutcome> Commit(const std::vector<StoredReading>& readings, const std::vector<Rejected>& rejected,
                                    const std::vector<std::pair<std::string, std::string>>& new_sites = {});
  /// Rejected rows deleted to stay within RejectedLimits, since the database was created.
  int64_t RejectedEvicted();
  /// (crusher, site) bindings learnt from the first site each crusher was heard from.
  std::vector<std::pair<std::string, std::string>> CrusherSites();

  /// Latest reading (by time, then seq) of every sensor of `crusher` and its reading count.
  struct SensorSummary {
    StoredReading latest;
    int64_t count = 0;
  };
  std::vector<SensorSummary> LatestPerSensor(const std::string& crusher);

  /// Readings of one sensor in [from_s, to_s], oldest first, at most `limit`, starting after
  /// `cursor` (from a previous page), payload left empty. Throws std::invalid_argument on a
  /// malformed cursor.
  Page Range(const std::string& crusher, const std::string& sensor, int64_t from_s, int64_t to_s, int limit,
             const std::string& cursor);

  /// Every reading of `crusher`, ordered by sensor then time (payload left empty).
  std::vector<StoredReading> All(const std::string& crusher);

  int64_t CountReadings(const std::string& crusher);
  /// Readings of one sensor of `crusher` (an index range count).
  int64_t CountReadings(const std::string& crusher, const std::string& sensor);
  /// The sensors `crusher` has readings of, in order (one index seek each, not a scan).
  std::vector<std::string> SensorsOf(const std::string& crusher);
  /// The latest reading (by time, then seq) of one sensor, payload left empty.
  std::optional<StoredReading> Latest(const std::string& crusher, const std::string& sensor);
  /// Visits the readings of one sensor with time in [from_s, to_s] through the time index alone,
  /// oldest first (newest first when `newest_first`), until `visit` returns false. Only what the
  /// index holds is read: seq, time, thickness, loops, flags (battery_mv, received_s 0, payload empty).
  /// `visit` runs on the calling thread, inside the query (it must not use this Store).
  void Walk(const std::string& crusher, const std::string& sensor, int64_t from_s, int64_t to_s, bool newest_first,
            const std::function<bool(const StoredReading&)>& visit);
  int64_t CountRejected();
  std::vector<Rejected> RejectedMessages(int limit);

  /// The campaigns of `crusher` stored so far, voided ones too, oldest first (by start, then as stored;
  /// none before its first reline).
  std::vector<CampaignRecord> Campaigns(const std::string& crusher);
  /// A reline in ONE transaction: `closed` (the running campaign, with its end, final scan and final
  /// readings) is stored or updated by its start, and `next` is stored. On any error nothing is
  /// committed and std::runtime_error is thrown.
  void Reline(const std::string& crusher, const CampaignRecord& closed, const CampaignRecord& next);
  /// Voids a reline in ONE transaction: `voided` (a stored campaign, by its id) gets its voided_s,
  /// voided_by, void_reason and reline_scan; the campaign `reopened_id` (the one its reline closed)
  /// runs again: no end, no final scan, no final readings. Throws std::runtime_error (nothing stored).
  void VoidReline(const CampaignRecord& voided, int64_t reopened_id);

  /// Stores `check`; false (nothing changed) when the crusher has one at that time already. Throws
  /// std::runtime_error (nothing stored).
  bool AddSettingCheck(const SettingCheckRecord& check);
  /// The crusher's measured settings, oldest first.
  std::vector<SettingCheckRecord> SettingChecks(const std::string& crusher);
  /// Stores the openings (opening_mm, opening_supported) of `checks`, stored ones keyed by crusher
  /// and time, in ONE transaction; returns how many rows changed. Throws std::runtime_error
  /// (nothing stored).
  int UpdateSettingCheckOpenings(const std::vector<SettingCheckRecord>& checks);

  /// Stores `alarm` (a new one when its id is 0) and appends `audit` (its alarm: the alarm's id)
  /// in ONE transaction; returns the alarm's id. Throws std::runtime_error (nothing stored).
  int64_t SaveAlarm(const AlarmRecord& alarm, AlarmAuditEntry audit);
  /// Every alarm not cleared, of every crusher, oldest first.
  std::vector<AlarmRecord> OpenAlarms();
  /// Alarms of `crusher`, newest first, at most `limit`: in `state` (empty: any) and, when cleared,
  /// cleared at or after `cleared_since_s`.
  std::vector<AlarmRecord> Alarms(const std::string& crusher, const std::string& state, int64_t cleared_since_s, int limit);
  std::optional<AlarmRecord> Alarm(int64_t id);
  /// The audit trail of alarm `id`, oldest first.
  std::vector<AlarmAuditEntry> AlarmAudit(int64_t id);
  /// The REST override of `crusher`'s alarm rules (an "alarms" object, docs/alarms.md), if any.
  std::optional<std::string> AlarmRules(const std::string& crusher);
  /// Stores the override and its audit entry (alarm 0, action "rules") in ONE transaction.
  void SaveAlarmRules(const std::string& crusher, const std::string& json, const AlarmAuditEntry& audit);

  /// Queues the notifications `make` gives for each alarm event audited since the last call (of
  /// any connection), and moves the cursor past them, in ONE transaction: an event is queued once,
  /// and none is skipped by a crash. Returns the rows queued. Throws std::runtime_error (nothing stored).
  int64_t QueueNotifications(const NotificationMaker& make);
  /// The oldest pending notification of each receiver (channel, target), oldest first.
  std::vector<NotificationRecord> PendingNotifications();
  /// Every notification, oldest first, at most `limit`.
  std::vector<NotificationRecord> Notifications(int limit);
  int64_t CountPendingNotifications();
  /// Stores a delivery attempt's outcome: state, attempts, next_attempt, done, last_error of `n`.
  void SaveNotificationAttempt(const NotificationRecord& n);

  void SaveDiagnosis(const std::string& crusher, int64_t time_s, const std::string& json);
  /// (time_s, json) of the latest diagnosis of `crusher`.
  std::optional<std::pair<int64_t, std::string>> LatestDiagnosis(const std::string& crusher);

 private:
  struct ReadOnlyTag {};
  Store(const std::filesystem::path& path, ReadOnlyTag);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A Store shared by several threads: it owns the store and the lock, and the store is reached only
/// through With(), which holds the lock for the whole call. The result is returned by value (no
/// reference into the store outlives the lock).
///
///   const int64_t n = read.With([&](Store& s) { return s.CountReadings(crusher); });
class LockedStore {
 public:
  explicit LockedStore(std::unique_ptr<Store> store) : store_(std::move(store)) {}
  LockedStore(const LockedStore&) = delete;
  LockedStore& operator=(const LockedStore&) = delete;

  /// Calls `use(store)` on the calling thread with the lock held; other threads' calls wait.
  template <class F>
  auto With(F&& use) {
    std::lock_guard<std::mutex> lock(mutex_);
    return std::forward<F>(use)(*store_);
  }

 private:
  std::unique_ptr<Store> store_;
  std::mutex mutex_;
};

}  // namespace lw::server
