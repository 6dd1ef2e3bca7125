// The server's rejected-message store at scale: committing N rejected readings (6 kB payloads, so
// each is truncated and digested) and then the same N again (every one a duplicate, found through
// the digest index), for N and 2N in one run. A store that scans per row (the 212 s single commit
// this replaced) shows a per-reading ratio near 2 between the sizes; an indexed one stays near 1.
// Not a test: a timing belongs here, not in ctest (tests/unit/server/test_store.cpp checks the
// counts of the same workload).
//   lw_bench_store_rejected [--readings N] [--reps R] [--dir D]   (defaults 10000, 3, /var/tmp)
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <unistd.h>

#include "server/store.hpp"
#include "../bench_stats.hpp"

namespace {

using lw::bench::Median;

struct Timing {
  double first_s = 0;   ///< N new rejected readings, one commit
  double second_s = 0;  ///< the same N again: duplicates
  long long stored = 0;
};

Timing RunOnce(const std::filesystem::path& dir, int n) {
  const std::filesystem::path db = dir / ("lw_bench_store_" + std::to_string(getpid()) + ".db");
  for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(db.string() + suffix);
  Timing t;
  {
    lw::server::RejectedLimits limits;
    limits.max_rows = 10LL * n;
    limits.max_bytes = 1LL << 40;
    lw::server::Store s(db.string(), limits);
    std::vector<lw::server::Rejected> batch;
    batch.reserve(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i)
      batch.push_back(
          {i, "", "{\"n\":" + std::to_string(i) + ",\"pad\":\"" + std::string(6000, 'z') + "\"}", "bad", "malformed"});
    const auto a = std::chrono::steady_clock::now();
    s.Commit({}, batch);
    const auto b = std::chrono::steady_clock::now();
    s.Commit({}, batch);
    const auto c = std::chrono::steady_clock::now();
    t.first_s = std::chrono::duration<double>(b - a).count();
    t.second_s = std::chrono::duration<double>(c - b).count();
    t.stored = s.CountRejected();
  }
  for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(db.string() + suffix);
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  int n = 10000, reps = 3;
  std::filesystem::path dir = "/var/tmp";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> const char* {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "lw_bench_store_rejected: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--readings") {
      n = std::atoi(value());
    } else if (a == "--reps") {
      reps = std::atoi(value());
    } else if (a == "--dir") {
      dir = value();
    } else if (a == "--help" || a == "-h") {
      std::printf("usage: lw_bench_store_rejected [--readings N] [--reps R] [--dir D]  (defaults 10000, 3, /var/tmp)\n");
      return 0;
    } else {
      std::fprintf(stderr, "lw_bench_store_rejected: unknown argument '%s' (see --help)\n", a.c_str());
      return 2;
    }
  }
  if (n < 100 || reps < 1) {
    std::fprintf(stderr, "lw_bench_store_rejected: --readings must be >= 100 and --reps >= 1\n");
    return 2;
  }
  std::vector<double> f1, s1, f2, s2;
  // Alternate the sizes so both see the same machine load.
  for (int r = 0; r < reps; ++r) {
    const Timing a = RunOnce(dir, n);
    const Timing b = RunOnce(dir, 2 * n);
    if (a.stored != n || b.stored != 2 * n) {
      std::fprintf(stderr, "lw_bench_store_rejected: stored %lld and %lld rejected readings, expected %d and %d\n", a.stored,
                   b.stored, n, 2 * n);
      return 1;
    }
    f1.push_back(a.first_s);
    s1.push_back(a.second_s);
    f2.push_back(b.first_s);
    s2.push_back(b.second_s);
    std::printf("rep %d: N=%d new %.3f s, duplicates %.3f s; 2N=%d new %.3f s, duplicates %.3f s\n", r + 1, n, a.first_s,
                a.second_s, 2 * n, b.first_s, b.second_s);
  }
  const double us1 = 1e6 * Median(f1) / n, us2 = 1e6 * Median(f2) / (2.0 * n);
  const double ud1 = 1e6 * Median(s1) / n, ud2 = 1e6 * Median(s2) / (2.0 * n);
  std::printf("new readings: %.1f us each at N, %.1f at 2N: ratio 2N / N per reading %.2f (linear: ~1, per-row scan: ~2)\n", us1,
              us2, us2 / us1);
  std::printf("duplicates:   %.1f us each at N, %.1f at 2N: ratio 2N / N per reading %.2f\n", ud1, ud2, ud2 / ud1);
  return 0;
}
