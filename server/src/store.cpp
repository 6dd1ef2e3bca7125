#include "server/store.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

#include "core/wear_map.hpp"

#include "core/sqlite.hpp"

namespace lw::server {
namespace {

using Db = core::sqlite::Database<std::runtime_error>;
using Stmt = core::sqlite::Statement<std::runtime_error>;
using Tx = core::sqlite::Transaction<std::runtime_error>;

constexpr int kSchemaVersion = 9;

StoredReading Row(const Stmt& s) {
  StoredReading r;
  r.crusher = s.Text(0);
  r.sensor = s.Text(1);
  r.seq = s.Int(2);
  r.time_s = s.Int(3);
  r.thickness_mm = s.Real(4);
  r.loops_intact = s.Int(5);
  r.flags = s.Int(6);
  r.battery_mv = s.Int(7);
  r.received_s = s.Int(8);
  r.payload = s.Text(9);
  return r;
}

/// Resets a statement when the scope ends, so no statement stays active between calls: an active
/// statement keeps the connection's read transaction (its WAL snapshot) open, and later queries
/// would not see newer commits.
class InUse {
 public:
  explicit InUse(Stmt& s) : s_(s) { s_.Reset(); }
  ~InUse() { s_.Reset(); }
  InUse(const InUse&) = delete;
  InUse& operator=(const InUse&) = delete;

 private:
  Stmt& s_;
};

}  // namespace

std::string MakeCursor(int64_t time_s, int64_t seq) {
  return "t" + std::to_string(time_s) + "s" + std::to_string(seq);
}

void ParseCursor(const std::string& cursor, int64_t* time_s, int64_t* seq) {
  const size_t s = cursor.find('s');
  try {
    if (cursor.size() < 4 || cursor[0] != 't' || s == std::string::npos) throw std::invalid_argument("");
    size_t used = 0;
    const std::string t = cursor.substr(1, s - 1), q = cursor.substr(s + 1);
    // Exactly t<int>s<int> as MakeCursor writes it: std::stoll alone takes " 1" and "+1" too.
    for (const std::string* part : {&t, &q}) {
      const size_t digits = part->rfind('-', 0) == 0 ? 1 : 0;
      if (part->size() == digits || part->find_first_not_of("0123456789", digits) != std::string::npos)
        throw std::invalid_argument("");
    }
    *time_s = std::stoll(t, &used);
    if (used != t.size()) throw std::invalid_argument("");
    *seq = std::stoll(q, &used);
    if (used != q.size()) throw std::invalid_argument("");
  } catch (const std::exception&) {
    throw std::invalid_argument("cursor '" + cursor + "' is not one this server issued");
  }
}

namespace {

/// Creates the database file readable by its owner only (0600) before SQLite opens it: SQLite gives
/// its -wal and -shm files the database file's mode. An existing file keeps its mode.
/// `path` as an SQLite URI opening it read-only and immutable (no -wal/-shm written, no locks).
std::string ImmutableUri(const std::string& path) {
  std::string uri = "file:";
  for (const char c : path) {
    if (c == '%' || c == '?' || c == '#') {
      static const char* kHex = "0123456789ABCDEF";
      uri += '%';
      uri += kHex[static_cast<unsigned char>(c) >> 4];
      uri += kHex[static_cast<unsigned char>(c) & 15];
    } else {
      uri += c;
    }
  }
  return uri + "?immutable=1";
}

void CreatePrivate(const std::string& path) {
  if (path.empty() || path == ":memory:" || path.rfind("file:", 0) == 0) return;  // not a file name
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd >= 0) ::close(fd);
}

}  // namespace

struct Store::Impl {
  Db db;
  Stmt insert, existing, insert_rejected, latest, range, all, count, count_rejected, rejected_list, save_diag, load_diag;
  Stmt rejected_seen, rejected_delete, meta_get, meta_add, sites_list, site_bind;
  Stmt count_sensor, next_sensor, walk_up, walk_down, latest_of, campaigns_list, campaign_put, campaign_void, campaign_reopen;
  Stmt rejected_oldest_of, rejected_classes;
  RejectedLimits limits;
  struct Size {
    int64_t rows = 0, bytes = 0;
  };
  /// The rejected table's size per reason class, counted once, then kept up to date by this (the
  /// only writing) connection.
  std::optional<std::map<std::string, Size>> rejected_size;
  Impl(const std::string& path, RejectedLimits l, bool read_only = false)
      : db(read_only ? ImmutableUri(path) : (CreatePrivate(path), path), "database",
           read_only ? SQLITE_OPEN_READONLY | SQLITE_OPEN_URI : SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE),
        insert(
            (read_only ? CheckVersion(db) : Init(db), db),
            "INSERT INTO readings(crusher, sensor, seq, time, thickness_mm, loops_intact, flags, battery_mv, received, payload)"
            " VALUES(?1,?2,?3,?4,?5,?6,?7,?8,?9,?10) ON CONFLICT DO NOTHING"),
        existing(db, "SELECT time, thickness_mm FROM readings WHERE crusher=?1 AND sensor=?2 AND seq=?3"),
        insert_rejected(
            db, "INSERT INTO rejected(received, topic, payload, reason, digest, bytes, class) VALUES(?1,?2,?3,?4,?5,?6,?7)"),
        latest(db,
               "SELECT crusher, sensor, seq, time, thickness_mm, loops_intact, flags, battery_mv, received, payload, n FROM ("
               " SELECT *, COUNT(*) OVER (PARTITION BY sensor) AS n,"
               " ROW_NUMBER() OVER (PARTITION BY sensor ORDER BY time DESC, seq DESC) AS k"
               " FROM readings WHERE crusher=?1) WHERE k=1 ORDER BY sensor"),
        // The readings JSON's columns only (never the payload). ?3 is the later of `from` and the
        // cursor's time, so the time index's range starts there: with the cursor's bound written as
        // an OR, SQLite began the range at the cursor's time, INT64_MIN on a first page, and walked
        // the sensor's index from its first reading. battery_mv and received are read from the row
        // (the index does not hold them): a primary-key look-up per reading returned.
        range(db,
              "SELECT seq, time, thickness_mm, loops_intact, flags, battery_mv, received FROM readings"
              " WHERE crusher=?1 AND sensor=?2 AND time>=?3 AND time<=?4 AND (time, seq)>(?5, ?6)"
              " ORDER BY time, seq LIMIT ?7"),
        // Everything but the raw payload: this feeds the wear and forecast computations.
        all(db,
            "SELECT crusher, sensor, seq, time, thickness_mm, loops_intact, flags, battery_mv, received, '' FROM readings"
            " WHERE crusher=?1 ORDER BY sensor, time, seq"),
        count(db, "SELECT COUNT(*) FROM readings WHERE crusher=?1"),
        count_rejected(db, "SELECT COUNT(*) FROM rejected"),
        rejected_list(db, "SELECT received, topic, payload, reason, class FROM rejected ORDER BY id DESC LIMIT ?1"),
        save_diag(db, "INSERT INTO diagnoses(crusher, time, json) VALUES(?1,?2,?3)"),
        load_diag(db, "SELECT time, json FROM diagnoses WHERE crusher=?1 ORDER BY id DESC LIMIT 1"),
        // A message resent by its publisher is quarantined once, not once per resend: an indexed
        // look-up of the SHA-256 of topic and full payload (not a scan comparing payloads).
        rejected_seen(db, "SELECT 1 FROM rejected WHERE digest=?1"),
        rejected_delete(db, "DELETE FROM rejected WHERE id=?1"),
        meta_get(db, "SELECT value FROM meta WHERE key=?1"),
        meta_add(db, "INSERT INTO meta(key, value) VALUES(?1, ?2) ON CONFLICT(key) DO UPDATE SET value=value+?2"),
        sites_list(db, "SELECT crusher, site FROM crusher_sites ORDER BY crusher"),
        site_bind(db, "INSERT INTO crusher_sites(crusher, site) VALUES(?1, ?2) ON CONFLICT(crusher) DO UPDATE SET site=?2"),
        count_sensor(db, "SELECT COUNT(*) FROM readings WHERE crusher=?1 AND sensor=?2"),
        next_sensor(db, "SELECT sensor FROM readings WHERE crusher=?1 AND sensor>?2 ORDER BY sensor LIMIT 1"),
        // Only the index's columns: battery_mv and received read as 0.
        walk_up(db,
                "SELECT crusher, sensor, seq, time, thickness_mm, loops_intact, flags, 0, 0, '' FROM readings"
                " WHERE crusher=?1 AND sensor=?2 AND time>=?3 AND time<=?4 ORDER BY time, seq"),
        walk_down(db,
                  "SELECT crusher, sensor, seq, time, thickness_mm, loops_intact, flags, 0, 0, '' FROM readings"
                  " WHERE crusher=?1 AND sensor=?2 AND time>=?3 AND time<=?4 ORDER BY time DESC, seq DESC"),
        latest_of(db,
                  "SELECT crusher, sensor, seq, time, thickness_mm, loops_intact, flags, battery_mv, received, '' FROM readings"
                  " WHERE crusher=?1 AND sensor=?2 ORDER BY time DESC, seq DESC LIMIT 1"),
        campaigns_list(db,
                       "SELECT id, start, end, thickness_new_mm, sensors, final_scan, final_readings, created, voided,"
                       " voided_by, void_reason, reline_scan FROM campaigns WHERE crusher=?1 ORDER BY start, id"),
        // A closed campaign that was stored when it began (its start is its key among the campaigns
        // not voided) gets its end here.
        campaign_put(db,
                     "INSERT INTO campaigns(crusher, start, end, thickness_new_mm, sensors, final_scan, final_readings, created)"
                     " VALUES(?1,?2,?3,?4,?5,?6,?7,?8) ON CONFLICT(crusher, start) WHERE voided IS NULL DO UPDATE SET end=?3,"
                     " final_scan=?6, final_readings=?7"),
        campaign_void(db, "UPDATE campaigns SET voided=?2, voided_by=?3, void_reason=?4, reline_scan=?5 WHERE id=?1"),
        campaign_reopen(db, "UPDATE campaigns SET end=NULL, final_scan=NULL, final_readings='[]' WHERE id=?1"),
        rejected_oldest_of(db, "SELECT id, bytes FROM rejected WHERE class=?1 ORDER BY id LIMIT 1"),
        rejected_classes(db, "SELECT class, COUNT(*), COALESCE(SUM(bytes), 0) FROM rejected GROUP BY class"),
        limits(l) {}

  /// The class that gives up its oldest row when the table is full: the one holding the most rows
  /// (or bytes, when the byte cap is what is reached), `incoming` on a tie. So a flood of one kind
  /// ends up evicting only itself once it holds the largest share, and every other class keeps at
  /// least an equal share of the table.
  std::string Victim(const std::map<std::string, Size>& sizes, const std::string& incoming, bool by_bytes) const {
    std::string victim = incoming;
    int64_t most = 0;
    if (const auto it = sizes.find(incoming); it != sizes.end()) most = by_bytes ? it->second.bytes : it->second.rows;
    for (const auto& [c, size] : sizes) {
      const int64_t n = by_bytes ? size.bytes : size.rows;
      if (n > most) most = n, victim = c;
    }
    return victim;
  }

  /// Stores rejected rows (each once), making room within the caps by Victim's rule; the
  /// evictions are counted in meta. Inside Commit's transaction.
  void Quarantine(const std::vector<Rejected>& rejected) {
    if (!rejected_size) {
      rejected_size.emplace();
      InUse use_classes(rejected_classes);
      while (rejected_classes.Step())
        (*rejected_size)[rejected_classes.Text(0)] = {rejected_classes.Int(1), rejected_classes.Int(2)};
    }
    std::map<std::string, Size> sizes = *rejected_size;  // committed only with the transaction
    Size total;
    for (const auto& [c, size] : sizes) total.rows += size.rows, total.bytes += size.bytes;
    int64_t evicted = 0;
    for (const Rejected& r : rejected) {
      const std::string digest = core::Sha256Hex(r.topic + '\n' + r.payload);
      {
        InUse use_seen(rejected_seen);
        rejected_seen.Bind(1, digest);
        if (rejected_seen.Step()) continue;
      }
      // Only the start of a large payload is kept (its size and digest identify it).
      std::string payload = r.payload;
      if (payload.size() > limits.max_payload_bytes) {
        payload.resize(limits.max_payload_bytes);
        payload += "... [truncated: " + std::to_string(r.payload.size()) + " bytes]";
      }
      const auto size = static_cast<int64_t>(r.topic.size() + payload.size() + r.reason.size());
      while (total.rows > 0 && (total.rows + 1 > limits.max_rows || total.bytes + size > limits.max_bytes)) {
        const std::string victim = Victim(sizes, r.reason_class, total.rows + 1 <= limits.max_rows);
        int64_t id = 0, b = 0;
        {
          InUse use_oldest(rejected_oldest_of);
          rejected_oldest_of.Bind(1, victim);
          if (!rejected_oldest_of.Step()) break;
          id = rejected_oldest_of.Int(0);
          b = rejected_oldest_of.Int(1);
        }
        InUse use_delete(rejected_delete);
        rejected_delete.Bind(1, id);
        rejected_delete.Step();
        --total.rows, total.bytes -= b;
        Size& v = sizes[victim];
        --v.rows, v.bytes -= b;
        if (v.rows <= 0) sizes.erase(victim);
        ++evicted;
      }
      InUse use_insert(insert_rejected);
      insert_rejected.Bind(1, r.received_s).Bind(2, r.topic).Bind(3, payload).Bind(4, r.reason).Bind(5, digest).Bind(6, size);
      insert_rejected.Bind(7, r.reason_class);
      insert_rejected.Step();
      ++total.rows, total.bytes += size;
      Size& c = sizes[r.reason_class];
      ++c.rows, c.bytes += size;
    }
    if (evicted > 0) {
      InUse use_meta(meta_add);
      meta_add.Bind(1, std::string("rejected_evicted")).Bind(2, evicted);
      meta_add.Step();
    }
    pending_size = std::move(sizes);
  }
  /// Quarantine's sizes, taken as rejected_size once its transaction commits.
  std::optional<std::map<std::string, Size>> pending_size;

  static void CheckVersion(const Db& db) {
    Stmt version(db, "PRAGMA user_version");
    version.Step();
    if (version.Int(0) != kSchemaVersion) {
      throw std::runtime_error("database " + db.path() + ": schema version " + std::to_string(version.Int(0)) +
                               ", not this server's (" + std::to_string(kSchemaVersion) +
                               "): cannot be read without upgrading it");
    }
  }

  static void Init(const Db& db) {
    int64_t v = 0;
    {
      Stmt version(db, "PRAGMA user_version");
      version.Step();
      v = version.Int(0);
    }
    if (v > kSchemaVersion) {
      throw std::runtime_error("database " + db.path() + ": schema version " + std::to_string(v) +
                               " is newer than this server's (" + std::to_string(kSchemaVersion) + ")");
    }
    // WAL + synchronous=FULL: a commit returns after the log is on disk, so a committed ack
    // survives kill -9 and power loss. Readers (REST) never block the writer.
    db.Exec("PRAGMA journal_mode=WAL");
    db.Exec("PRAGMA synchronous=FULL");
    db.Exec(
        "CREATE TABLE IF NOT EXISTS readings ("
        " crusher TEXT NOT NULL, sensor TEXT NOT NULL, seq INTEGER NOT NULL,"
        " time INTEGER NOT NULL, thickness_mm REAL NOT NULL, loops_intact INTEGER NOT NULL,"
        " flags INTEGER NOT NULL, battery_mv INTEGER NOT NULL, received INTEGER NOT NULL, payload TEXT NOT NULL,"
        " PRIMARY KEY (crusher, sensor, seq)) WITHOUT ROWID;"
        // Per sensor by time, covering what wear and forecasts read (thickness, flags, loops): the
        // state rebuilt at startup (server/live_state.hpp) walks it without touching the rows. It
        // replaces readings_by_time (crusher, sensor, time, seq), its prefix; built once on a database
        // that has the older index.
        "CREATE INDEX IF NOT EXISTS readings_by_sensor_time ON readings(crusher, sensor, time, seq, thickness_mm, flags, "
        "loops_intact);"
        "DROP INDEX IF EXISTS readings_by_time;"
        "CREATE TABLE IF NOT EXISTS rejected (id INTEGER PRIMARY KEY AUTOINCREMENT, received INTEGER NOT NULL,"
        " topic TEXT NOT NULL, payload TEXT NOT NULL, reason TEXT NOT NULL);"
        "CREATE TABLE IF NOT EXISTS diagnoses (id INTEGER PRIMARY KEY AUTOINCREMENT, crusher TEXT NOT NULL,"
        " time INTEGER NOT NULL, json TEXT NOT NULL);");
    if (v < 2) {
      // Version 2: rejected rows carry a digest (indexed duplicate check) and their size (the cap);
      // crushers are bound to their site; counters that outlive a restart.
      Tx tx(db);
      Stmt cols(db, "SELECT COUNT(*) FROM pragma_table_info('rejected') WHERE name='digest'");
      cols.Step();
      if (cols.Int(0) == 0) {
        db.Exec("ALTER TABLE rejected ADD COLUMN digest TEXT; ALTER TABLE rejected ADD COLUMN bytes INTEGER NOT NULL DEFAULT 0;");
      }
      db.Exec(
          "UPDATE rejected SET bytes=length(CAST(topic AS BLOB))+length(CAST(payload AS BLOB))+length(CAST(reason AS BLOB))"
          " WHERE bytes=0;"
          "DROP INDEX IF EXISTS rejected_by_topic;"
          "CREATE INDEX IF NOT EXISTS rejected_by_digest ON rejected(digest);"
          "CREATE TABLE IF NOT EXISTS crusher_sites (crusher TEXT PRIMARY KEY, site TEXT NOT NULL);"
          "CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value INTEGER NOT NULL);"
          "PRAGMA user_version=2;");
      tx.Commit();
    }
    if (v < 3) {
      // Version 3: liner campaigns (relines, docs/campaigns.md). end is NULL while a campaign runs;
      // final_scan is the old liner's end-of-life scan text (NULL: none).
      Tx tx(db);
      db.Exec(
          "CREATE TABLE IF NOT EXISTS campaigns (crusher TEXT NOT NULL, start INTEGER NOT NULL, end INTEGER,"
          " thickness_new_mm REAL NOT NULL, sensors TEXT NOT NULL, final_scan TEXT, final_readings TEXT NOT NULL,"
          " created INTEGER NOT NULL, PRIMARY KEY (crusher, start));"
          "PRAGMA user_version=3;");
      tx.Commit();
    }
    if (v < 4) {
      // Version 4: rejected rows carry their reason class (Rejected::reason_class), the unit the
      // table's caps share out. Rows from before have the class '' (one class of their own).
      Tx tx(db);
      db.Exec(
          "ALTER TABLE rejected ADD COLUMN class TEXT NOT NULL DEFAULT '';"
          "CREATE INDEX IF NOT EXISTS rejected_by_class ON rejected(class, id);"
          "PRAGMA user_version=4;");
      tx.Commit();
    }
    if (v < 5) {
      // Version 5: alarms (docs/alarms.md), their audit trail and the rules set over REST. An
      // alarm's row lives from its raise to its clear and is kept after; value and threshold are
      // NULL for the rules without one.
      Tx tx(db);
      db.Exec(
          "CREATE TABLE IF NOT EXISTS alarms (id INTEGER PRIMARY KEY AUTOINCREMENT, crusher TEXT NOT NULL, rule TEXT NOT NULL,"
          " subject TEXT NOT NULL, severity TEXT NOT NULL, state TEXT NOT NULL, since INTEGER NOT NULL, detail TEXT NOT NULL,"
          " value REAL, threshold REAL, acknowledged INTEGER, acknowledged_by TEXT NOT NULL DEFAULT '', cleared INTEGER);"
          "CREATE INDEX IF NOT EXISTS alarms_by_crusher ON alarms(crusher, id);"
          "CREATE TABLE IF NOT EXISTS alarm_audit (id INTEGER PRIMARY KEY AUTOINCREMENT, alarm INTEGER NOT NULL,"
          " time INTEGER NOT NULL, action TEXT NOT NULL, who TEXT NOT NULL, detail TEXT NOT NULL);"
          "CREATE INDEX IF NOT EXISTS alarm_audit_by_alarm ON alarm_audit(alarm, id);"
          "CREATE TABLE IF NOT EXISTS alarm_rules (crusher TEXT PRIMARY KEY, json TEXT NOT NULL);"
          "PRAGMA user_version=5;");
      tx.Commit();
    }
    if (v < 6) {
      // Version 6: the notification outbox (docs/alarms.md, *Notifications*): one row per alarm
      // event and receiver, queued in one transaction with the cursor `notified_audit` (the last
      // alarm_audit row queued), kept after delivery with its state. The cursor starts at the
      // newest audit row: the alarms of before are not sent.
      Tx tx(db);
      db.Exec(
          "CREATE TABLE IF NOT EXISTS notifications (id INTEGER PRIMARY KEY AUTOINCREMENT, audit INTEGER NOT NULL,"
          " channel TEXT NOT NULL, target TEXT NOT NULL, event TEXT NOT NULL, body TEXT NOT NULL, created INTEGER NOT NULL,"
          " state TEXT NOT NULL DEFAULT 'pending', attempts INTEGER NOT NULL DEFAULT 0, next_attempt INTEGER NOT NULL,"
          " done INTEGER, last_error TEXT NOT NULL DEFAULT '');"
          "CREATE INDEX IF NOT EXISTS notifications_pending ON notifications(state, target, id);"
          "INSERT OR IGNORE INTO meta(key, value) SELECT 'notified_audit', COALESCE(MAX(id), 0) FROM alarm_audit;"
          "PRAGMA user_version=6;");
      tx.Commit();
    }
    if (v < 7) {
      // Version 7: a reline posted by mistake is voided, not deleted (docs/campaigns.md, *Voiding a
      // reline*): its row is kept with when, by whom and why, and the scan its reline carried
      // (reline_scan, moved off the campaign it had closed, which runs again). A start is the key
      // only among the campaigns not voided (a reline at the voided one's time may follow): the
      // table is rebuilt with a row id and a partial unique index.
      Tx tx(db);
      db.Exec(
          "CREATE TABLE campaigns_v7 (id INTEGER PRIMARY KEY AUTOINCREMENT, crusher TEXT NOT NULL, start INTEGER NOT NULL,"
          " end INTEGER, thickness_new_mm REAL NOT NULL, sensors TEXT NOT NULL, final_scan TEXT, final_readings TEXT NOT NULL,"
          " created INTEGER NOT NULL, voided INTEGER, voided_by TEXT NOT NULL DEFAULT '', void_reason TEXT NOT NULL DEFAULT '',"
          " reline_scan TEXT);"
          "INSERT INTO campaigns_v7(crusher, start, end, thickness_new_mm, sensors, final_scan, final_readings, created)"
          " SELECT crusher, start, end, thickness_new_mm, sensors, final_scan, final_readings, created FROM campaigns"
          " ORDER BY crusher, start;"
          "DROP TABLE campaigns;"
          "ALTER TABLE campaigns_v7 RENAME TO campaigns;"
          "CREATE UNIQUE INDEX campaigns_by_start ON campaigns(crusher, start) WHERE voided IS NULL;"
          "PRAGMA user_version=7;");
      tx.Commit();
    }
    if (v < 8) {
      // Version 8: closed-side settings measured on the crusher (docs/wear.md, *Setting*), one per
      // crusher and time; opening_mm is the concave's opening the server estimated at that time
      // (NULL: not supported then), which the measured CSS anchors.
      Tx tx(db);
      db.Exec(
          "CREATE TABLE IF NOT EXISTS setting_checks (crusher TEXT NOT NULL, time INTEGER NOT NULL, css_mm REAL NOT NULL, "
          "opening_mm REAL,"
          " by TEXT NOT NULL, note TEXT NOT NULL DEFAULT '', recorded INTEGER NOT NULL, PRIMARY KEY (crusher, time));"
          "PRAGMA user_version=8;");
      tx.Commit();
    }
    if (v < 9) {
      // Version 9: whether a setting check's opening came from a supported discharge ring (an
      // unsupported one now keeps its central estimate instead of NULL).
      Tx tx(db);
      Stmt cols(db, "SELECT COUNT(*) FROM pragma_table_info('setting_checks') WHERE name='opening_supported'");
      cols.Step();
      if (cols.Int(0) == 0) {
        db.Exec(
            "ALTER TABLE setting_checks ADD COLUMN opening_supported INTEGER NOT NULL DEFAULT 0;"
            "UPDATE setting_checks SET opening_supported=1 WHERE opening_mm IS NOT NULL;");
      }
      db.Exec("PRAGMA user_version=9;");
      tx.Commit();
    }
  }
};

Store::Store(const std::filesystem::path& path, RejectedLimits limits) {
  const std::string name = path.string();
  const bool file = !name.empty() && name != ":memory:" && name.rfind("file:", 0) != 0;
  std::error_code ec;
  const bool existed = file && std::filesystem::exists(path, ec);
  // SQLite takes an empty file for a new database: a database truncated to 0 bytes (a failed
  // copy, a file system repair) would silently start again with no history.
  if (existed && std::filesystem::is_regular_file(path, ec) && std::filesystem::file_size(path, ec) == 0 && !ec) {
    throw std::runtime_error("database " + name +
                             " is an empty file (0 bytes), not a linerwatch database: restore it from a backup, or delete "
                             "it to start a new database");
  }
  try {
    impl_ = std::make_unique<Impl>(name, limits);
  } catch (...) {
    // Not left behind as an empty file of our making (e.g. on a full disk): the next start would refuse it.
    if (file && !existed && std::filesystem::file_size(path, ec) == 0 && !ec) std::filesystem::remove(path, ec);
    throw;
  }
}
Store::Store(const std::filesystem::path& path, ReadOnlyTag)
    : impl_(std::make_unique<Impl>(path.string(), RejectedLimits{}, true)) {}
std::unique_ptr<Store> Store::OpenReadOnly(const std::filesystem::path& path) {
  return std::unique_ptr<Store>(new Store(path, ReadOnlyTag{}));
}
Store::~Store() = default;

std::vector<InsertOutcome> Store::Commit(const std::vector<StoredReading>& readings, const std::vector<Rejected>& rejected,
                                         const std::vector<std::pair<std::string, std::string>>& new_sites) {
  Impl& im = *impl_;
  std::vector<InsertOutcome> out;
  out.reserve(readings.size());
  Tx tx(im.db);
  for (const StoredReading& r : readings) {
    InUse use_insert(im.insert);
    im.insert.Bind(1, r.crusher).Bind(2, r.sensor).Bind(3, r.seq).Bind(4, r.time_s).Bind(5, r.thickness_mm);
    im.insert.Bind(6, r.loops_intact).Bind(7, r.flags).Bind(8, r.battery_mv).Bind(9, r.received_s).Bind(10, r.payload);
    im.insert.Step();
    if (im.insert.Changes() == 1) {
      out.push_back(InsertOutcome::kStored);
      continue;
    }
    InUse use_existing(im.existing);
    im.existing.Bind(1, r.crusher).Bind(2, r.sensor).Bind(3, r.seq);
    const bool same =
        im.existing.Step() && im.existing.Int(0) == r.time_s && std::fabs(im.existing.Real(1) - r.thickness_mm) < 1e-9;
    out.push_back(same ? InsertOutcome::kDuplicate : InsertOutcome::kConflict);
  }
  for (const auto& [crusher, site] : new_sites) {
    InUse use_bind(im.site_bind);
    im.site_bind.Bind(1, crusher).Bind(2, site);
    im.site_bind.Step();
  }
  if (!rejected.empty()) {
    im.Quarantine(rejected);
    tx.Commit();
    im.rejected_size = std::move(im.pending_size);
    return out;
  }
  tx.Commit();
  return out;
}

int64_t Store::RejectedEvicted() {
  Impl& im = *impl_;
  InUse use_meta(im.meta_get);
  im.meta_get.Bind(1, std::string("rejected_evicted"));
  return im.meta_get.Step() ? im.meta_get.Int(0) : 0;
}

std::vector<std::pair<std::string, std::string>> Store::CrusherSites() {
  Impl& im = *impl_;
  std::vector<std::pair<std::string, std::string>> out;
  InUse use_sites(im.sites_list);
  while (im.sites_list.Step()) out.emplace_back(im.sites_list.Text(0), im.sites_list.Text(1));
  return out;
}

std::vector<Store::SensorSummary> Store::LatestPerSensor(const std::string& crusher) {
  Impl& im = *impl_;
  std::vector<SensorSummary> out;
  InUse use_latest(im.latest);
  im.latest.Bind(1, crusher);
  while (im.latest.Step()) out.push_back({Row(im.latest), im.latest.Int(10)});
  return out;
}

Page Store::Range(const std::string& crusher, const std::string& sensor, int64_t from_s, int64_t to_s, int limit,
                  const std::string& cursor) {
  Impl& im = *impl_;
  int64_t after_t = INT64_MIN, after_seq = INT64_MIN;
  if (!cursor.empty()) ParseCursor(cursor, &after_t, &after_seq);
  Page page;
  page.readings.reserve(static_cast<size_t>(std::clamp(limit, 0, 63)) + 1);  // a day of hourly readings without regrowing
  InUse use_range(im.range);
  im.range.Bind(1, crusher).Bind(2, sensor).Bind(3, std::max(from_s, after_t)).Bind(4, to_s).Bind(5, after_t);
  im.range.Bind(6, after_seq).Bind(7, static_cast<int64_t>(limit) + 1);
  while (im.range.Step()) {
    StoredReading& r = page.readings.emplace_back();
    r.crusher = crusher;
    r.sensor = sensor;
    r.seq = im.range.Int(0);
    r.time_s = im.range.Int(1);
    r.thickness_mm = im.range.Real(2);
    r.loops_intact = im.range.Int(3);
    r.flags = im.range.Int(4);
    r.battery_mv = im.range.Int(5);
    r.received_s = im.range.Int(6);
  }
  if (page.readings.size() > static_cast<size_t>(limit)) {
    page.readings.resize(static_cast<size_t>(limit));
    page.next_cursor = MakeCursor(page.readings.back().time_s, page.readings.back().seq);
  }
  return page;
}

std::vector<StoredReading> Store::All(const std::string& crusher) {
  Impl& im = *impl_;
  std::vector<StoredReading> out;
  InUse use_all(im.all);
  im.all.Bind(1, crusher);
  while (im.all.Step()) out.push_back(Row(im.all));
  return out;
}

int64_t Store::CountReadings(const std::string& crusher) {
  Impl& im = *impl_;
  InUse use_count(im.count);
  im.count.Bind(1, crusher);
  im.count.Step();
  return im.count.Int(0);
}

int64_t Store::CountReadings(const std::string& crusher, const std::string& sensor) {
  Impl& im = *impl_;
  InUse use_count(im.count_sensor);
  im.count_sensor.Bind(1, crusher).Bind(2, sensor);
  im.count_sensor.Step();
  return im.count_sensor.Int(0);
}

std::vector<std::string> Store::SensorsOf(const std::string& crusher) {
  Impl& im = *impl_;
  std::vector<std::string> out;
  std::string after;  // "" sorts before every sensor id (ids are not empty)
  while (true) {
    InUse use_next(im.next_sensor);
    im.next_sensor.Bind(1, crusher).Bind(2, after);
    if (!im.next_sensor.Step()) break;
    after = im.next_sensor.Text(0);
    out.push_back(after);
  }
  return out;
}

std::optional<StoredReading> Store::Latest(const std::string& crusher, const std::string& sensor) {
  Impl& im = *impl_;
  InUse use_latest(im.latest_of);
  im.latest_of.Bind(1, crusher).Bind(2, sensor);
  if (!im.latest_of.Step()) return std::nullopt;
  return Row(im.latest_of);
}

void Store::Walk(const std::string& crusher, const std::string& sensor, int64_t from_s, int64_t to_s, bool newest_first,
                 const std::function<bool(const StoredReading&)>& visit) {
  Impl& im = *impl_;
  Stmt& s = newest_first ? im.walk_down : im.walk_up;
  InUse use_walk(s);
  s.Bind(1, crusher).Bind(2, sensor).Bind(3, from_s).Bind(4, to_s);
  StoredReading r;  // one for every row: no allocation per reading (startup walks millions)
  r.crusher = crusher;
  r.sensor = sensor;
  while (s.Step()) {
    r.seq = s.Int(2);
    r.time_s = s.Int(3);
    r.thickness_mm = s.Real(4);
    r.loops_intact = s.Int(5);
    r.flags = s.Int(6);
    if (!visit(r)) break;
  }
}

int64_t Store::CountRejected() {
  Impl& im = *impl_;
  InUse use_count_rejected(im.count_rejected);
  im.count_rejected.Step();
  return im.count_rejected.Int(0);
}

std::vector<Rejected> Store::RejectedMessages(int limit) {
  Impl& im = *impl_;
  std::vector<Rejected> out;
  InUse use_rejected_list(im.rejected_list);
  im.rejected_list.Bind(1, static_cast<int64_t>(limit));
  while (im.rejected_list.Step()) {
    out.push_back({im.rejected_list.Int(0), im.rejected_list.Text(1), im.rejected_list.Text(2), im.rejected_list.Text(3),
                   im.rejected_list.Text(4)});
  }
  return out;
}

std::vector<CampaignRecord> Store::Campaigns(const std::string& crusher) {
  Impl& im = *impl_;
  std::vector<CampaignRecord> out;
  Stmt& s = im.campaigns_list;
  InUse use_list(s);
  s.Bind(1, crusher);
  while (s.Step()) {
    CampaignRecord c;
    c.id = s.Int(0);
    c.start_s = s.Int(1);
    if (!s.IsNull(2)) c.end_s = s.Int(2);
    c.thickness_new_mm = s.Real(3);
    c.sensors_json = s.Text(4);
    if (!s.IsNull(5)) c.final_scan = s.Text(5);
    c.final_readings_json = s.Text(6);
    c.created_s = s.Int(7);
    if (!s.IsNull(8)) c.voided_s = s.Int(8);
    c.voided_by = s.Text(9);
    c.void_reason = s.Text(10);
    if (!s.IsNull(11)) c.reline_scan = s.Text(11);
    out.push_back(std::move(c));
  }
  return out;
}

void Store::Reline(const std::string& crusher, const CampaignRecord& closed, const CampaignRecord& next) {
  Impl& im = *impl_;
  Tx tx(im.db);
  for (const CampaignRecord* c : {&closed, &next}) {
    Stmt& s = im.campaign_put;
    InUse use_put(s);
    s.Bind(1, crusher).Bind(2, c->start_s).Bind(4, c->thickness_new_mm).Bind(5, c->sensors_json);
    if (c->end_s) s.Bind(3, *c->end_s);
    if (!c->final_scan.empty()) s.Bind(6, c->final_scan);
    s.Bind(7, c->final_readings_json).Bind(8, c->created_s);
    s.Step();
  }
  tx.Commit();
}

void Store::VoidReline(const CampaignRecord& voided, int64_t reopened_id) {
  Impl& im = *impl_;
  Tx tx(im.db);
  {
    Stmt& s = im.campaign_void;
    InUse use_void(s);
    s.Bind(1, voided.id).Bind(2, voided.voided_s.value_or(0)).Bind(3, voided.voided_by).Bind(4, voided.void_reason);
    if (!voided.reline_scan.empty()) s.Bind(5, voided.reline_scan);
    s.Step();
  }
  {
    Stmt& s = im.campaign_reopen;
    InUse use_reopen(s);
    s.Bind(1, reopened_id);
    s.Step();
  }
  tx.Commit();
}

bool Store::AddSettingCheck(const SettingCheckRecord& c) {
  Impl& im = *impl_;
  Stmt add(im.db,
           "INSERT INTO setting_checks(crusher, time, css_mm, opening_mm, by, note, recorded, opening_supported)"
           " VALUES(?1,?2,?3,?4,?5,?6,?7,?8) ON CONFLICT(crusher, time) DO NOTHING");
  add.Bind(1, c.crusher).Bind(2, c.time_s).Bind(3, c.css_mm).Bind(5, c.by).Bind(6, c.note).Bind(7, c.recorded_s);
  add.Bind(8, static_cast<int64_t>(c.opening_supported ? 1 : 0));
  if (c.opening_mm) add.Bind(4, *c.opening_mm);
  add.Step();
  return add.Changes() > 0;
}

std::vector<SettingCheckRecord> Store::SettingChecks(const std::string& crusher) {
  Impl& im = *impl_;
  Stmt list(im.db,
            "SELECT crusher, time, css_mm, opening_mm, by, note, recorded, opening_supported FROM setting_checks"
            " WHERE crusher=?1 ORDER BY time");
  list.Bind(1, crusher);
  std::vector<SettingCheckRecord> out;
  while (list.Step()) {
    SettingCheckRecord c{list.Text(0),     list.Int(1),  list.Real(2), std::nullopt,
                         list.Int(7) != 0, list.Text(4), list.Text(5), list.Int(6)};
    if (!list.IsNull(3)) c.opening_mm = list.Real(3);
    out.push_back(std::move(c));
  }
  return out;
}

int Store::UpdateSettingCheckOpenings(const std::vector<SettingCheckRecord>& checks) {
  Impl& im = *impl_;
  Tx tx(im.db);
  Stmt update(im.db,
              "UPDATE setting_checks SET opening_mm=?3, opening_supported=?4 WHERE crusher=?1 AND time=?2"
              " AND (opening_mm IS NOT ?3 OR opening_supported IS NOT ?4)");
  int changed = 0;
  for (const SettingCheckRecord& c : checks) {
    InUse use(update);
    update.Bind(1, c.crusher).Bind(2, c.time_s).Bind(4, static_cast<int64_t>(c.opening_supported ? 1 : 0));
    if (c.opening_mm) update.Bind(3, *c.opening_mm);
    update.Step();
    changed += update.Changes();
  }
  tx.Commit();
  return changed;
}

namespace {

constexpr const char* kAlarmColumns =
    "id, crusher, rule, subject, severity, state, since, detail, value, threshold, acknowledged, acknowledged_by, cleared";

AlarmRecord AlarmRow(const Stmt& s) {
  AlarmRecord a;
  a.id = s.Int(0);
  a.crusher = s.Text(1);
  a.rule = s.Text(2);
  a.subject = s.Text(3);
  a.severity = s.Text(4);
  a.state = s.Text(5);
  a.since_s = s.Int(6);
  a.detail = s.Text(7);
  if (!s.IsNull(8)) a.value = s.Real(8);
  if (!s.IsNull(9)) a.threshold = s.Real(9);
  if (!s.IsNull(10)) a.acknowledged_s = s.Int(10);
  a.acknowledged_by = s.Text(11);
  if (!s.IsNull(12)) a.cleared_s = s.Int(12);
  return a;
}

std::vector<AlarmRecord> AlarmRows(Stmt& s) {
  std::vector<AlarmRecord> out;
  while (s.Step()) out.push_back(AlarmRow(s));
  return out;
}

void AppendAudit(const Db& db, const AlarmAuditEntry& e) {
  Stmt add(db, "INSERT INTO alarm_audit(alarm, time, action, who, detail) VALUES(?1,?2,?3,?4,?5)");
  add.Bind(1, e.alarm).Bind(2, e.time_s).Bind(3, e.action).Bind(4, e.by).Bind(5, e.detail);
  add.Step();
}

}  // namespace

int64_t Store::SaveAlarm(const AlarmRecord& a, AlarmAuditEntry audit) {
  Impl& im = *impl_;
  Tx tx(im.db);
  // Alarms change a few times a day: statements made per call, not kept.
  Stmt put(im.db, a.id == 0 ? "INSERT INTO alarms(crusher, rule, subject, severity, state, since, detail, value, threshold,"
                              " acknowledged, acknowledged_by, cleared) VALUES(?2,?3,?4,?5,?6,?7,?8,?9,?10,?11,?12,?13)"
                              " RETURNING id"
                            : "UPDATE alarms SET severity=?5, state=?6, detail=?8, acknowledged=?11, acknowledged_by=?12,"
                              " cleared=?13 WHERE id=?1 RETURNING id");
  put.Bind(1, a.id).Bind(2, a.crusher).Bind(3, a.rule).Bind(4, a.subject).Bind(5, a.severity).Bind(6, a.state);
  put.Bind(7, a.since_s).Bind(8, a.detail).Bind(12, a.acknowledged_by);
  if (a.value) put.Bind(9, *a.value);
  if (a.threshold) put.Bind(10, *a.threshold);
  if (a.acknowledged_s) put.Bind(11, *a.acknowledged_s);
  if (a.cleared_s) put.Bind(13, *a.cleared_s);
  if (!put.Step()) throw std::runtime_error("database " + im.db.path() + ": no alarm " + std::to_string(a.id) + " to update");
  audit.alarm = put.Int(0);
  put.Reset();
  AppendAudit(im.db, audit);
  tx.Commit();
  return audit.alarm;
}

std::vector<AlarmRecord> Store::OpenAlarms() {
  Stmt q(impl_->db, (std::string("SELECT ") + kAlarmColumns + " FROM alarms WHERE state!='cleared' ORDER BY id").c_str());
  return AlarmRows(q);
}

std::vector<AlarmRecord> Store::Alarms(const std::string& crusher, const std::string& state, int64_t cleared_since_s, int limit) {
  Stmt q(impl_->db, (std::string("SELECT ") + kAlarmColumns +
                     " FROM alarms WHERE crusher=?1 AND (?2='' OR state=?2) AND (state!='cleared' OR cleared>=?3)"
                     " ORDER BY id DESC LIMIT ?4")
                        .c_str());
  q.Bind(1, crusher).Bind(2, state).Bind(3, cleared_since_s).Bind(4, limit);
  return AlarmRows(q);
}

std::optional<AlarmRecord> Store::Alarm(int64_t id) {
  Stmt q(impl_->db, (std::string("SELECT ") + kAlarmColumns + " FROM alarms WHERE id=?1").c_str());
  q.Bind(1, id);
  std::vector<AlarmRecord> rows = AlarmRows(q);
  if (rows.empty()) return std::nullopt;
  return rows.front();
}

std::vector<AlarmAuditEntry> Store::AlarmAudit(int64_t id) {
  Stmt q(impl_->db, "SELECT alarm, time, action, who, detail FROM alarm_audit WHERE alarm=?1 ORDER BY id");
  q.Bind(1, id);
  std::vector<AlarmAuditEntry> out;
  while (q.Step()) out.push_back({q.Int(0), q.Int(1), q.Text(2), q.Text(3), q.Text(4)});
  return out;
}

std::optional<std::string> Store::AlarmRules(const std::string& crusher) {
  Stmt q(impl_->db, "SELECT json FROM alarm_rules WHERE crusher=?1");
  q.Bind(1, crusher);
  if (!q.Step()) return std::nullopt;
  return q.Text(0);
}

void Store::SaveAlarmRules(const std::string& crusher, const std::string& json, const AlarmAuditEntry& audit) {
  Impl& im = *impl_;
  Tx tx(im.db);
  Stmt put(im.db, "INSERT INTO alarm_rules(crusher, json) VALUES(?1, ?2) ON CONFLICT(crusher) DO UPDATE SET json=?2");
  put.Bind(1, crusher).Bind(2, json);
  put.Step();
  AppendAudit(im.db, audit);
  tx.Commit();
}

int64_t Store::QueueNotifications(const NotificationMaker& make) {
  Impl& im = *impl_;
  Tx tx(im.db);
  int64_t cursor = 0;
  {
    Stmt c(im.db, "SELECT value FROM meta WHERE key='notified_audit'");
    if (c.Step()) cursor = c.Int(0);
  }
  // Rule changes (alarm 0) are audited but are not alarm events.
  Stmt events(im.db, "SELECT id, alarm, time, action, who, detail FROM alarm_audit WHERE id>?1 ORDER BY id");
  events.Bind(1, cursor);
  std::vector<std::pair<int64_t, AlarmAuditEntry>> audit;
  while (events.Step())
    audit.push_back({events.Int(0), {events.Int(1), events.Int(2), events.Text(3), events.Text(4), events.Text(5)}});
  events.Reset();
  if (audit.empty()) return 0;
  int64_t queued = 0;
  Stmt put(im.db,
           "INSERT INTO notifications(audit, channel, target, event, body, created, next_attempt) VALUES(?1,?2,?3,?4,?5,?6,0)");
  for (const auto& [id, entry] : audit) {
    if (entry.alarm == 0) continue;
    const std::optional<AlarmRecord> alarm = Alarm(entry.alarm);
    if (!alarm) continue;
    for (const QueuedNotification& n : make(*alarm, entry, id)) {
      put.Bind(1, id).Bind(2, n.channel).Bind(3, n.target).Bind(4, entry.action).Bind(5, n.body).Bind(6, entry.time_s);
      put.Step();
      put.Reset();
      ++queued;
    }
  }
  Stmt advance(im.db, "INSERT INTO meta(key, value) VALUES('notified_audit', ?1) ON CONFLICT(key) DO UPDATE SET value=?1");
  advance.Bind(1, audit.back().first);
  advance.Step();
  tx.Commit();
  return queued;
}

namespace {

constexpr const char* kNotificationColumns =
    "id, audit, channel, target, event, body, created, state, attempts, next_attempt, done, last_error";

NotificationRecord NotificationRow(const Stmt& s) {
  NotificationRecord n;
  n.id = s.Int(0);
  n.audit = s.Int(1);
  n.channel = s.Text(2);
  n.target = s.Text(3);
  n.event = s.Text(4);
  n.body = s.Text(5);
  n.created_s = s.Int(6);
  n.state = s.Text(7);
  n.attempts = s.Int(8);
  n.next_attempt_s = s.Int(9);
  if (!s.IsNull(10)) n.done_s = s.Int(10);
  n.last_error = s.Text(11);
  return n;
}

}  // namespace

std::vector<NotificationRecord> Store::PendingNotifications() {
  // The oldest pending row of each receiver only: a receiver gets its events in order, a later
  // one never before an earlier one that is still being retried.
  Stmt q(impl_->db, (std::string("SELECT ") + kNotificationColumns +
                     " FROM notifications WHERE id IN (SELECT MIN(id) FROM notifications WHERE state='pending'"
                     " GROUP BY channel, target) ORDER BY id")
                        .c_str());
  std::vector<NotificationRecord> out;
  while (q.Step()) out.push_back(NotificationRow(q));
  return out;
}

std::vector<NotificationRecord> Store::Notifications(int limit) {
  Stmt q(impl_->db, (std::string("SELECT ") + kNotificationColumns + " FROM notifications ORDER BY id LIMIT ?1").c_str());
  q.Bind(1, limit);
  std::vector<NotificationRecord> out;
  while (q.Step()) out.push_back(NotificationRow(q));
  return out;
}

int64_t Store::CountPendingNotifications() {
  Stmt q(impl_->db, "SELECT COUNT(*) FROM notifications WHERE state='pending'");
  q.Step();
  return q.Int(0);
}

void Store::SaveNotificationAttempt(const NotificationRecord& n) {
  Impl& im = *impl_;
  Tx tx(im.db);
  Stmt put(im.db, "UPDATE notifications SET state=?2, attempts=?3, next_attempt=?4, done=?5, last_error=?6 WHERE id=?1");
  put.Bind(1, n.id).Bind(2, n.state).Bind(3, n.attempts).Bind(4, n.next_attempt_s).Bind(6, n.last_error);
  if (n.done_s) put.Bind(5, *n.done_s);
  put.Step();
  tx.Commit();
}

void Store::SaveDiagnosis(const std::string& crusher, int64_t time_s, const std::string& json) {
  Impl& im = *impl_;
  Tx tx(im.db);
  InUse use_save_diag(im.save_diag);
  im.save_diag.Bind(1, crusher).Bind(2, time_s).Bind(3, json);
  im.save_diag.Step();
  tx.Commit();
}

std::optional<std::pair<int64_t, std::string>> Store::LatestDiagnosis(const std::string& crusher) {
  Impl& im = *impl_;
  InUse use_load_diag(im.load_diag);
  im.load_diag.Bind(1, crusher);
  if (!im.load_diag.Step()) return std::nullopt;
  return std::make_pair(im.load_diag.Int(0), im.load_diag.Text(1));
}

}  // namespace lw::server
