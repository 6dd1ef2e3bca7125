#include "gateway/spool.hpp"

#include <sqlite3.h>

#include <algorithm>
#include <utility>

namespace lw::gateway {
namespace {

// A prepared statement that resets itself; errors become SpoolError naming the file.
class Stmt {
 public:
  Stmt(sqlite3* db, const std::string& path, const char* sql) : db_(db), path_(path) {
    if (sqlite3_prepare_v2(db, sql, -1, &stmt_, nullptr) != SQLITE_OK) Fail("prepare");
  }
  ~Stmt() { sqlite3_finalize(stmt_); }
  Stmt(const Stmt&) = delete;
  Stmt& operator=(const Stmt&) = delete;

  Stmt& Bind(int i, const std::string& v) {
    sqlite3_bind_text(stmt_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Stmt& Bind(int i, int64_t v) {
    sqlite3_bind_int64(stmt_, i, v);
    return *this;
  }
  /// Steps once: true when a row is available.
  bool Step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    Fail("step");
    return false;
  }
  void Reset() {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }
  int64_t Int(int col) const { return sqlite3_column_int64(stmt_, col); }
  std::string Text(int col) const {
    const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(stmt_, col));
    return p ? std::string(p, static_cast<size_t>(sqlite3_column_bytes(stmt_, col))) : std::string();
  }

 private:
  [[noreturn]] void Fail(const char* what) {
    throw SpoolError("spool " + path_ + ": " + what + ": " + sqlite3_errmsg(db_));
  }
  sqlite3* db_;
  const std::string& path_;
  sqlite3_stmt* stmt_ = nullptr;
};

}  // namespace

struct Spool::Db {
  sqlite3* handle = nullptr;
  ~Db() { sqlite3_close(handle); }
};

namespace {
void Exec(sqlite3* db, const std::string& path, const char* sql) {
  char* err = nullptr;
  if (sqlite3_exec(db, sql, nullptr, nullptr, &err) != SQLITE_OK) {
    std::string msg = err ? err : sqlite3_errmsg(db);
    sqlite3_free(err);
    throw SpoolError("spool " + path + ": " + msg);
  }
}

// Rolls back unless committed: an exception in the middle of a batch stores nothing.
class Transaction {
 public:
  Transaction(sqlite3* db, const std::string& path) : db_(db), path_(path) { Exec(db, path, "BEGIN IMMEDIATE"); }
  ~Transaction() {
    if (!done_) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
  }
  void Commit() {
    Exec(db_, path_, "COMMIT");
    done_ = true;
  }

 private:
  sqlite3* db_;
  const std::string& path_;
  bool done_ = false;
};
}  // namespace

Spool::Spool(const std::string& path, size_t max_records)
    : db_(std::make_unique<Db>()), path_(path), max_records_(max_records ? max_records : 1) {
  if (sqlite3_open_v2(path.c_str(), &db_->handle, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr) != SQLITE_OK) {
    throw SpoolError("spool " + path + ": cannot open: " +
                     (db_->handle ? sqlite3_errmsg(db_->handle) : "out of memory"));
  }
  sqlite3_busy_timeout(db_->handle, 5000);
  // WAL + synchronous=FULL: a COMMIT returns only after the WAL is fsynced, so a record acked to
  // the sensor survives kill -9 and power loss.
  Exec(db_->handle, path_, "PRAGMA journal_mode=WAL");
  Exec(db_->handle, path_, "PRAGMA synchronous=FULL");
  Exec(db_->handle, path_,
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
  Stmt count(db_->handle, path_, "SELECT COUNT(*) FROM records");
  if (count.Step()) depth_ = static_cast<size_t>(count.Int(0));
}

Spool::~Spool() = default;

std::vector<InsertOutcome> Spool::Insert(const std::vector<SpoolRecord>& records) {
  std::vector<InsertOutcome> out;
  out.reserve(records.size());
  sqlite3* db = db_->handle;
  Transaction tx(db, path_);
  Stmt exists(db, path_, "SELECT 1 FROM records WHERE sensor = ?1 AND seq = ?2");
  Stmt insert(db, path_,
              "INSERT INTO records(sensor, seq, received_ms, heartbeat, payload) VALUES (?1, ?2, ?3, ?4, ?5)");
  Stmt evict(db, path_,
             "DELETE FROM records WHERE id = (SELECT id FROM records WHERE heartbeat = 1 ORDER BY id LIMIT 1)");
  size_t depth = depth_;
  uint64_t evicted = 0;
  for (const SpoolRecord& r : records) {
    exists.Bind(1, r.sensor).Bind(2, static_cast<int64_t>(r.seq));
    const bool duplicate = exists.Step();
    exists.Reset();
    if (duplicate) {
      out.push_back(InsertOutcome::kDuplicate);
      continue;
    }
    if (depth >= max_records_) {
      evict.Step();
      evict.Reset();
      if (sqlite3_changes(db) == 0) {
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
    ++depth;
    out.push_back(InsertOutcome::kStored);
  }
  tx.Commit();
  depth_ = depth;
  evicted_ += evicted;
  return out;
}

std::vector<int64_t> Spool::Confirm(const std::string& sensor, const std::vector<uint32_t>& seqs) {
  std::vector<int64_t> received;
  if (seqs.empty()) return received;
  sqlite3* db = db_->handle;
  Transaction tx(db, path_);
  Stmt del(db, path_, "DELETE FROM records WHERE sensor = ?1 AND seq = ?2 RETURNING received_ms");
  for (uint32_t seq : seqs) {
    del.Bind(1, sensor).Bind(2, static_cast<int64_t>(seq));
    while (del.Step()) received.push_back(del.Int(0));
    del.Reset();
  }
  tx.Commit();
  depth_ -= std::min(depth_, received.size());
  return received;
}

std::vector<SpoolRecord> Spool::Heads(size_t per_sensor) const {
  std::vector<SpoolRecord> out;
  sqlite3* db = db_->handle;
  // Distinct sensors by a loose index scan over UNIQUE(sensor, seq): one index seek per sensor,
  // not a scan of the whole spool (a spool after a long outage holds hundreds of thousands).
  Stmt sensors(db, path_,
               "WITH RECURSIVE s(sensor) AS ("
               " SELECT MIN(sensor) FROM records"
               " UNION ALL SELECT (SELECT MIN(sensor) FROM records WHERE sensor > s.sensor) FROM s WHERE s.sensor IS NOT NULL)"
               " SELECT sensor FROM s WHERE sensor IS NOT NULL");
  Stmt head(db, path_,
            "SELECT seq, received_ms, heartbeat, payload FROM records WHERE sensor = ?1 ORDER BY seq LIMIT ?2");
  while (sensors.Step()) {
    const std::string sensor = sensors.Text(0);
    head.Bind(1, sensor).Bind(2, static_cast<int64_t>(per_sensor));
    while (head.Step()) {
      SpoolRecord r;
      r.sensor = sensor;
      r.seq = static_cast<uint32_t>(head.Int(0));
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
  Stmt insert(db_->handle, path_,
              "INSERT INTO devices(address, sensor, node_identifier, device_type, first_seen_ms)"
              " VALUES (?1, ?2, ?3, ?4, ?5)"
              " ON CONFLICT(address, sensor) DO UPDATE SET"
              "  node_identifier = excluded.node_identifier, device_type = excluded.device_type"
              " WHERE excluded.node_identifier != node_identifier OR excluded.device_type != device_type");
  Stmt exists(db_->handle, path_, "SELECT 1 FROM devices WHERE address = ?1 AND sensor = ?2");
  exists.Bind(1, device.address).Bind(2, device.sensor);
  const bool known = exists.Step();
  insert.Bind(1, device.address)
      .Bind(2, device.sensor)
      .Bind(3, device.node_identifier)
      .Bind(4, static_cast<int64_t>(device.device_type))
      .Bind(5, device.first_seen_ms);
  insert.Step();
  return !known || sqlite3_changes(db_->handle) > 0;
}

std::vector<DeviceEntry> Spool::Devices() const {
  std::vector<DeviceEntry> out;
  Stmt all(db_->handle, path_,
           "SELECT address, sensor, node_identifier, device_type, first_seen_ms FROM devices ORDER BY first_seen_ms, address");
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
