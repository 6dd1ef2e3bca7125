#include "support/pipeline_ledger.hpp"

#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include <httplib.h>  // after Eigen users (<resolv.h> defines _res)

namespace lw::test {

std::vector<Produced> LoadLedger(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("ledger " + path + ": cannot read");
  std::string line;
  std::getline(in, line);
  if (line != "sensor_id,seq,time,thickness_mm") throw std::runtime_error("ledger " + path + ": bad header '" + line + "'");
  std::vector<Produced> out;
  for (size_t n = 2; std::getline(in, line); ++n) {
    std::istringstream fields(line);
    std::string sensor, seq, time, mm;
    std::getline(fields, sensor, ',');
    std::getline(fields, seq, ',');
    std::getline(fields, time, ',');
    std::getline(fields, mm);
    const auto t = core::ParseIsoTime(time);
    try {
      if (!t || sensor.empty()) throw std::invalid_argument("time");
      out.push_back({sensor, std::stoll(seq), *t, std::stod(mm)});
    } catch (const std::exception&) {
      throw std::runtime_error("ledger " + path + ":" + std::to_string(n) + ": malformed line '" + line + "'");
    }
  }
  return out;
}

double VirtualDay(const std::string& clock_file, core::TimePoint installed_at) {
  std::ifstream in(clock_file);
  long long ms = 0;
  if (!(in >> ms)) return -1;
  return core::DaysBetween(installed_at, core::TimePoint(std::chrono::seconds(ms / 1000)));
}

long StoredCount(int http_port, const std::string& crusher) {
  httplib::Client http("127.0.0.1", http_port);
  http.set_connection_timeout(2);
  http.set_read_timeout(5);
  auto res = http.Get("/api/v1/crushers/" + crusher + "/sensors");
  if (!res || res->status != 200) return -1;
  const nlohmann::json j = nlohmann::json::parse(res->body, nullptr, false);
  if (j.is_discarded() || !j.contains("sensors")) return -1;
  long total = 0;
  for (const auto& s : j["sensors"]) total += s.value("reading_count", 0L);
  return total;
}

LedgerCheck CompareLedger(const std::vector<Produced>& ledger, const std::vector<server::StoredReading>& rows) {
  LedgerCheck c;
  c.produced = ledger.size();
  c.stored = rows.size();
  std::map<std::pair<std::string, int64_t>, std::vector<const server::StoredReading*>> by_key;
  for (const auto& r : rows) by_key[{r.sensor, r.seq}].push_back(&r);
  auto note = [&c](const std::string& what) {
    if (c.first_problem.empty()) c.first_problem = what;
  };
  std::map<std::pair<std::string, int64_t>, bool> in_ledger;
  for (const Produced& p : ledger) {
    const std::string key = p.sensor + "/" + std::to_string(p.seq);
    if (in_ledger.count({p.sensor, p.seq})) {
      note("the ledger lists " + key + " twice");
      ++c.duplicated;  // a seq handed out twice by a board: one of the two cannot be stored
      continue;
    }
    in_ledger[{p.sensor, p.seq}] = true;
    const auto it = by_key.find({p.sensor, p.seq});
    if (it == by_key.end()) {
      ++c.lost;
      note("lost " + key);
      continue;
    }
    const server::StoredReading& r = *it->second.front();
    if (r.time_s != p.time.time_since_epoch().count() || r.thickness_mm != p.thickness_mm) {
      ++c.mismatched;
      note("stored " + key + " with time " + std::to_string(r.time_s) + " and " + std::to_string(r.thickness_mm) + " mm");
    }
  }
  for (const auto& [key, v] : by_key) {
    const size_t expected = in_ledger.count(key) ? 1 : 0;
    if (v.size() > expected) {
      c.duplicated += v.size() - expected;
      note("stored " + key.first + "/" + std::to_string(key.second) + (expected ? " more than once" : " but never produced"));
    }
  }
  return c;
}

}  // namespace lw::test
