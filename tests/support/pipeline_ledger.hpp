#pragma once
// Shared by the end-to-end test and the chaos soak (bench/chaos): the simulator's ledger of
// produced readings, the virtual clock file, the server's stored count over HTTP, and the
// exactly-once comparison of a ledger with what the server stored.
//
//   const auto ledger = lw::test::LoadLedger(dir + "/ledger.csv");   // throws std::runtime_error
//   const auto check = lw::test::CompareLedger(ledger, store.All(crusher));
//   // check.lost, check.duplicated, check.mismatched (0 each when stored exactly once)
#include <cstdint>
#include <string>
#include <vector>

#include "core/time.hpp"
#include "server/store.hpp"

namespace lw::test {

/// One line of `linerwatch-sim run --ledger`: a reading a virtual sensor produced.
struct Produced {
  std::string sensor;
  int64_t seq = 0;
  core::TimePoint time{};
  double thickness_mm = 0;
};

/// Reads a ledger CSV (sensor_id,seq,time,thickness_mm). Throws std::runtime_error naming the
/// file and line when the header or a line is malformed or the file cannot be read.
std::vector<Produced> LoadLedger(const std::string& path);

/// Virtual days since `installed_at`, from the simulator's --clock-out file (-1 before it exists).
double VirtualDay(const std::string& clock_file, core::TimePoint installed_at);

/// Sum of reading_count over the crusher's sensors from the server's HTTP API on 127.0.0.1:port
/// (-1 when the server does not answer).
long StoredCount(int http_port, const std::string& crusher);

/// Ledger vs stored rows of one crusher, keyed by (sensor, seq).
struct LedgerCheck {
  size_t produced = 0;        ///< ledger readings
  size_t stored = 0;          ///< rows
  size_t lost = 0;            ///< ledger readings with no row
  size_t duplicated = 0;      ///< rows beyond one per ledger reading (a key twice, or a key the ledger lacks)
  size_t mismatched = 0;      ///< rows of a ledger reading with another time or thickness
  std::string first_problem;  ///< e.g. "lost 1003/57", empty when none
  bool exactly_once() const { return lost == 0 && duplicated == 0 && mismatched == 0; }
};
LedgerCheck CompareLedger(const std::vector<Produced>& ledger, const std::vector<server::StoredReading>& rows);

}  // namespace lw::test
