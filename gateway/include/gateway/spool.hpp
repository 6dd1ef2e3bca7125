#pragma once
/// Durable store-and-forward spool (SQLite, WAL, synchronous=FULL). The only file in the gateway
/// that includes sqlite3.h is spool.cpp. A record stays here from the moment it is received until
/// the server confirms it is committed to its database; Insert() returns only after the record is
/// on disk, so the sensor may be acked afterwards. Not thread-safe: one thread owns a Spool.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <map>
#include <set>
#include <string>
#include <vector>

namespace lw::gateway {

/// Any SQLite failure (open, disk full, corruption), with the file name and SQLite's message.
class SpoolError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One sensor record as spooled: identity, bookkeeping and the JSON message to publish.
struct SpoolRecord {
  std::string sensor;  ///< decimal sensor id as on MQTT
  uint32_t seq = 0;
  int64_t received_ms = 0;  ///< Unix ms when the gateway received it
  bool heartbeat = false;   ///< carries kFlagHeartbeat: the first to go when the spool is full
  std::string payload;      ///< the reading message (docs/mqtt.md)
};

enum class InsertOutcome {
  kStored,        ///< new record, durable
  kDuplicate,     ///< (sensor, seq) already spooled (a sensor retransmission): durable too
  kRejectedFull,  ///< spool full and no heartbeat record to give up: NOT stored, do not ack
};

/// A device seen on the radio network (device registry).
struct DeviceEntry {
  std::string address;          ///< 64-bit address, 16 upper-case hex digits
  std::string sensor;           ///< decimal sensor id, empty for a node seen only by identification
  std::string node_identifier;  ///< NI string from a 0x95 frame, may be empty
  int device_type = -1;         ///< 0 coordinator, 1 router, 2 end device, -1 unknown
  int64_t first_seen_ms = 0;
};

class Spool {
 public:
  /// Opens or creates the spool at `path`. `max_records` (>= 1) bounds the number of records.
  /// Throws SpoolError.
  Spool(const std::string& path, size_t max_records);
  ~Spool();
  Spool(const Spool&) = delete;
  Spool& operator=(const Spool&) = delete;

  /// Stores records in one transaction (one fsync). Full-spool policy, per record: when the spool
  /// holds max_records, the oldest spooled heartbeat record is deleted to make room (counted in
  /// evicted()); when there is none, the new record is rejected. Returns one outcome per record.
  /// Throws SpoolError (nothing of the batch is stored then).
  std::vector<InsertOutcome> Insert(const std::vector<SpoolRecord>& records);
  /// The same, and in the same transaction (before the records, so that the full-spool policy
  /// sees the room they make) deletes the `release` pairs as Confirm does: released records
  /// become durable with the batch's fsync. Throws SpoolError (nothing deleted or stored then).
  std::vector<InsertOutcome> Insert(const std::vector<SpoolRecord>& records,
                                    const std::map<std::string, std::vector<uint32_t>>& release);
  /// The same, and records the registry `devices` in that transaction too (a sender's first
  /// entry costs no fsync of its own); (*devices_changed)[i] is what RecordDevice(devices[i])
  /// would have returned. Throws SpoolError (nothing deleted, stored or recorded then).
  std::vector<InsertOutcome> Insert(const std::vector<SpoolRecord>& records,
                                    const std::map<std::string, std::vector<uint32_t>>& release,
                                    const std::vector<DeviceEntry>& devices, std::vector<bool>* devices_changed);

  /// Deletes the confirmed (sensor, seq) pairs; returns the received_ms of each record actually
  /// deleted (unknown pairs are ignored). Throws SpoolError.
  std::vector<int64_t> Confirm(const std::string& sensor, const std::vector<uint32_t>& seqs);
  /// The same for several sensors, in one transaction.
  std::vector<int64_t> Confirm(const std::map<std::string, std::vector<uint32_t>>& seqs);

  /// Per sensor, its `per_sensor` lowest-seq records, in seq order; sensors in id order (text).
  std::vector<SpoolRecord> Heads(size_t per_sensor) const;
  /// The same for the named sensors only (one index seek each).
  std::vector<SpoolRecord> Heads(size_t per_sensor, const std::set<std::string>& sensors) const;
  /// The same with a number of records of its own for each named sensor; records whose seq is in
  /// `skip` (of their sensor) are left out of the result but count towards the number.
  std::vector<SpoolRecord> Heads(const std::map<std::string, size_t>& per_sensor,
                                 const std::map<std::string, std::vector<uint32_t>>& skip = {}) const;

  size_t depth() const { return depth_; }
  size_t max_records() const { return max_records_; }
  /// Heartbeat records deleted to make room since this Spool was opened.
  uint64_t evicted() const { return evicted_; }

  /// Records a device; returns true when this (address, sensor) pair was new or its node
  /// identification changed.
  bool RecordDevice(const DeviceEntry& device);
  /// Registry entries, oldest first; only those of `address` when it is not empty.
  std::vector<DeviceEntry> Devices(const std::string& address = "") const;

 private:
  struct Db;
  std::unique_ptr<Db> db_;
  std::string path_;
  size_t max_records_;
  size_t depth_ = 0;
  uint64_t evicted_ = 0;
};

}  // namespace lw::gateway
