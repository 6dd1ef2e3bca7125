#include "gateway/spool.hpp"

#include <sqlite3.h>

#include "core/sqlite.hpp"

#include <algorithm>
#include <map>
#include <set>
#include <utility>

namespace lw::gateway {
namespace {
using Stmt = core::sqlite::Statement<SpoolError>;
using Transaction = core::sqlite::Transaction<SpoolError>;
}  // namespace

struct Spool::Db {
  core::sqlite::Database<SpoolError> database;
  // Statements of the hot paths, prepared once (created after the schema, see the constructor):
  // preparing them on every call cost about as much as running them.
  std::unique_ptr<Stmt> exists, insert, evict, del, head, sync_normal, sync_full, device_exists, device_upsert;
  explicit Db(const std::string& path) : database(path, "spool") {}
  void Prepare() {
    exists = std::make_unique<Stmt>(database, "SELECT 1 FROM records WHERE sensor = ?1 AND seq = ?2");
    // A retransmission of a spooled record changes nothing (sqlite3_changes() tells it apart).
    insert =
        std::make_unique<Stmt>(database,
                               "INSERT INTO records(sensor, seq, received_ms, heartbeat, payload) VALUES (?1, ?2, ?3, ?4, ?5)"
                               " ON CONFLICT(sensor, seq) DO NOTHING");
    evict = std::make_unique<Stmt>(
        database, "DELETE FROM records WHERE id = (SELECT id FROM records WHERE heartbeat = 1 ORDER BY id LIMIT 1)");
    // A run of consecutive seqs in one statement (a batch's commit ack names a run).
    del =
        std::make_unique<Stmt>(database, "DELETE FROM records WHERE sensor = ?1 AND seq BETWEEN ?2 AND ?3 RETURNING received_ms");
    head = std::make_unique<Stmt>(
        database, "SELECT seq, received_ms, heartbeat, payload FROM records WHERE sensor = ?1 ORDER BY seq LIMIT ?2");
    sync_normal = std::make_unique<Stmt>(database, "PRAGMA synchronous=NORMAL");
    sync_full = std::make_unique<Stmt>(database, "PRAGMA synchronous=FULL");
    device_exists = std::make_unique<Stmt>(database, "SELECT 1 FROM devices WHERE address = ?1 AND sensor = ?2");
    device_upsert =
        std::make_unique<Stmt>(database,
                               "INSERT INTO devices(address, sensor, node_identifier, device_type, first_seen_ms)"
                               " VALUES (?1, ?2, ?3, ?4, ?5)"
                               " ON CONFLICT(address, sensor) DO UPDATE SET"
                               "  node_identifier = excluded.node_identifier, device_type = excluded.device_type"
                               " WHERE excluded.node_identifier != node_identifier OR excluded.device_type != device_type");
  }
  /// A statement ready to bind: reset (also after a step that threw).
  static Stmt& Fresh(const std::unique_ptr<Stmt>& s) {
    s->Reset();
    return *s;
  }
  /// Deletes the (sensor, seq) pairs inside the caller's transaction; appends the received_ms of
  /// each record deleted.
  void Delete(const std::map<std::string, std::vector<uint32_t>>& seqs_of, std::vector<int64_t>* received) {
    Stmt& d = Fresh(del);
    std::vector<uint32_t> sorted;
    for (const auto& [sensor, seqs] : seqs_of) {
      sorted.assign(seqs.begin(), seqs.end());
      std::sort(sorted.begin(), sorted.end());
      sorted.erase(std::unique(sorted.begin(), sorted.end()), sorted.end());
      // Each run of consecutive seqs [first, last]: exactly the seqs named there.
      for (size_t i = 0; i < sorted.size();) {
        size_t j = i + 1;
        while (j < sorted.size() && sorted[j] == sorted[j - 1] + 1) ++j;
        d.Bind(1, sensor).Bind(2, static_cast<int64_t>(sorted[i])).Bind(3, static_cast<int64_t>(sorted[j - 1]));
        while (d.Step()) received->push_back(d.Int(0));
        d.Reset();
        i = j;
      }
    }
  }
  /// Records a registry entry inside the caller's transaction (or on its own); true when the
  /// (address, sensor) pair was new or its node identification changed.
  bool RecordDevice(const DeviceEntry& device) {
    Stmt& known_stmt = Fresh(device_exists);
    known_stmt.Bind(1, device.address).Bind(2, device.sensor);
    const bool known = known_stmt.Step();
    known_stmt.Reset();
    Stmt& upsert = Fresh(device_upsert);
    upsert.Bind(1, device.address)
        .Bind(2, device.sensor)
        .Bind(3, device.node_identifier)
        .Bind(4, static_cast<int64_t>(device.device_type))
        .Bind(5, device.first_seen_ms);
    upsert.Step();
    upsert.Reset();
    return !known || sqlite3_changes(database.get()) > 0;
  }
};

Spool::Spool(const std::string& path, size_t max_records)
    : db_(std::make_unique<Db>(path)), path_(path), max_records_(max_records ? max_records : 1) {
  // WAL + synchronous=FULL: a COMMIT returns only after the WAL is fsynced, so a record acked to
  // the sensor survives kill -9 and power loss.
  db_->database.Exec("PRAGMA journal_mode=WAL");
  db_->database.Exec("PRAGMA synchronous=FULL");
  db_->database.Exec(
      "CREATE TABLE IF NOT EXISTS records ("
      " id INTEGER PRIMARY KEY AUTOINCREMENT,"
      " sensor TEXT NOT NULL, seq INTEGER NOT NULL, received_ms INTEGER NOT NULL,"
      " heartbeat INTEGER NOT NULL, payload TEXT NOT NULL,"
      " UNIQUE(sensor, seq));"
      "CREATE INDEX IF NOT EXISTS records_heartbeat ON records(heartbeat, id);"
      "CREATE TABLE IF NOT EXISTS devices ("
      " address TEXT NOT NULL, sensor TEXT NOT NULL, node_identifier TEXT NOT NULL,"
      " device_type INTEGER NOT NULL, first_seen_ms INTEGER NOT NULL,"
      " PRIMARY KEY(address, sensor));");
  Stmt count(db_->database, "SELECT COUNT(*) FROM records");
  if (count.Step()) depth_ = static_cast<size_t>(count.Int(0));
  db_->Prepare();
}

Spool::~Spool() = default;

std::vector<InsertOutcome> Spool::Insert(const std::vector<SpoolRecord>& records) {
  return Insert(records, {});
}

std::vector<InsertOutcome> Spool::Insert(const std::vector<SpoolRecord>& records,
                                         const std::map<std::string, std::vector<uint32_t>>& release) {
  return Insert(records, release, {}, nullptr);
}

std::vector<InsertOutcome> Spool::Insert(const std::vector<SpoolRecord>& records,
                                         const std::map<std::string, std::vector<uint32_t>>& release,
                                         const std::vector<DeviceEntry>& devices, std::vector<bool>* devices_changed) {
  std::vector<InsertOutcome> out;
  out.reserve(records.size());
  Db& db = *db_;
  Transaction tx(db.database);
  // The released records go first: the full-spool policy below sees the room they make.
  std::vector<int64_t> released;
  db.Delete(release, &released);
  size_t depth = depth_ - std::min(depth_, released.size());
  uint64_t evicted = 0;
  Stmt& exists = Db::Fresh(db.exists);
  Stmt& insert = Db::Fresh(db.insert);
  Stmt& evict = Db::Fresh(db.evict);
  for (const SpoolRecord& r : records) {
    if (depth >= max_records_) {
      // Full: a retransmission of a spooled record is still a duplicate (acked again); only a
      // new record gives up the oldest heartbeat, or is rejected.
      exists.Bind(1, r.sensor).Bind(2, static_cast<int64_t>(r.seq));
      const bool duplicate = exists.Step();
      exists.Reset();
      if (duplicate) {
        out.push_back(InsertOutcome::kDuplicate);
        continue;
      }
      evict.Step();
      evict.Reset();
      if (sqlite3_changes(db.database.get()) == 0) {
        out.push_back(InsertOutcome::kRejectedFull);
        continue;
      }
      --depth;
      ++evicted;
    }
    insert.Bind(1, r.sensor)
        .Bind(2, static_cast<int64_t>(r.seq))
        .Bind(3, r.received_ms)
        .Bind(4, r.heartbeat ? 1 : 0)
        .Bind(5, r.payload);
    insert.Step();
    insert.Reset();
    if (sqlite3_changes(db.database.get()) == 0) {
      out.push_back(InsertOutcome::kDuplicate);
      continue;
    }
    ++depth;
    out.push_back(InsertOutcome::kStored);
  }
  std::vector<bool> changed;
  changed.reserve(devices.size());
  for (const DeviceEntry& d : devices) changed.push_back(db.RecordDevice(d));
  tx.Commit();
  depth_ = depth;
  evicted_ += evicted;
  if (devices_changed) *devices_changed = std::move(changed);
  return out;
}

std::vector<int64_t> Spool::Confirm(const std::string& sensor, const std::vector<uint32_t>& seqs) {
  return Confirm(std::map<std::string, std::vector<uint32_t>>{{sensor, seqs}});
}

std::vector<int64_t> Spool::Confirm(const std::map<std::string, std::vector<uint32_t>>& seqs_of) {
  std::vector<int64_t> received;
  size_t any = 0;
  for (const auto& [sensor, seqs] : seqs_of) any += seqs.size();
  if (any == 0) return received;
  Db& db = *db_;
  // A deletion need not wait for the disk: were it lost with the power, the record would only be
  // published again and the server, which stores by (sensor, seq), would ack it again. The next
  // insert's fsync (synchronous=FULL) makes it durable with the WAL frames before it. Without
  // this, every commit ack cost an fsync: 100 sensors at --window 1 made ~180 records/s.
  Db::Fresh(db.sync_normal).Step();
  struct FullAgain {
    Db& db;
    ~FullAgain() {
      try {
        Db::Fresh(db.sync_full).Step();
      } catch (const SpoolError&) {
        sqlite3_exec(db.database.get(), "PRAGMA synchronous=FULL", nullptr, nullptr, nullptr);
      }
    }
  } full_again{db};
  Transaction tx(db.database);
  db.Delete(seqs_of, &received);
  tx.Commit();
  depth_ -= std::min(depth_, received.size());
  return received;
}

std::vector<SpoolRecord> Spool::Heads(size_t per_sensor) const {
  const auto& db = db_->database;
  // Distinct sensors by a loose index scan over UNIQUE(sensor, seq): one index seek per sensor,
  // not a scan of the whole spool (a spool after a long outage holds hundreds of thousands).
  Stmt sensors(db,
               "WITH RECURSIVE s(sensor) AS ("
               " SELECT MIN(sensor) FROM records"
               " UNION ALL SELECT (SELECT MIN(sensor) FROM records WHERE sensor > s.sensor) FROM s WHERE s.sensor IS NOT NULL)"
               " SELECT sensor FROM s WHERE sensor IS NOT NULL");
  std::set<std::string> all;
  while (sensors.Step()) all.insert(sensors.Text(0));
  return Heads(per_sensor, all);
}

std::vector<SpoolRecord> Spool::Heads(size_t per_sensor, const std::set<std::string>& sensors) const {
  std::map<std::string, size_t> limits;
  for (const std::string& sensor : sensors) limits.emplace_hint(limits.end(), sensor, per_sensor);
  return Heads(limits);
}

std::vector<SpoolRecord> Spool::Heads(const std::map<std::string, size_t>& per_sensor,
                                      const std::map<std::string, std::vector<uint32_t>>& skip) const {
  std::vector<SpoolRecord> out;
  Stmt& head = Db::Fresh(db_->head);
  static const std::vector<uint32_t> kNone;
  for (const auto& [sensor, limit] : per_sensor) {
    const auto skipped = skip.find(sensor);
    const std::vector<uint32_t>& left_out = skipped == skip.end() ? kNone : skipped->second;
    head.Bind(1, sensor).Bind(2, static_cast<int64_t>(limit));
    while (head.Step()) {
      const auto seq = static_cast<uint32_t>(head.Int(0));
      if (std::find(left_out.begin(), left_out.end(), seq) != left_out.end()) continue;
      SpoolRecord r;
      r.sensor = sensor;
      r.seq = seq;
      r.received_ms = head.Int(1);
      r.heartbeat = head.Int(2) != 0;
      r.payload = head.Text(3);
      out.push_back(std::move(r));
    }
    head.Reset();
  }
  return out;
}

bool Spool::RecordDevice(const DeviceEntry& device) {
  return db_->RecordDevice(device);
}

std::vector<DeviceEntry> Spool::Devices(const std::string& address) const {
  std::vector<DeviceEntry> out;
  Stmt all(db_->database,
           "SELECT address, sensor, node_identifier, device_type, first_seen_ms FROM devices"
           " WHERE ?1 = '' OR address = ?1 ORDER BY first_seen_ms, address");
  all.Bind(1, address);
  while (all.Step()) {
    DeviceEntry d;
    d.address = all.Text(0);
    d.sensor = all.Text(1);
    d.node_identifier = all.Text(2);
    d.device_type = static_cast<int>(all.Int(3));
    d.first_seen_ms = all.Int(4);
    out.push_back(std::move(d));
  }
  return out;
}

}  // namespace lw::gateway
