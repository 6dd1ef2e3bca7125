#pragma once
// Shared by the libFuzzer targets (docs/fuzzing.md): the failure report and a scratch directory for
// entry points that take a path.
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <string_view>

namespace lw::fuzz {

/// A property the target checks failed: print it and abort, so libFuzzer saves the input.
[[noreturn]] inline void Fail(const std::string& what) {
  std::fprintf(stderr, "fuzz property violated: %s\n", what.c_str());
  std::fflush(stderr);
  std::abort();
}
inline void Check(bool ok, const std::string& what) {
  if (!ok) Fail(what);
}

/// One scratch directory per fuzzer process under $TMPDIR (or /tmp), removed at exit.
inline const std::filesystem::path& ScratchDir() {
  static const std::filesystem::path dir = [] {
    const char* tmp = std::getenv("TMPDIR");
    std::string tmpl = std::string(tmp && *tmp ? tmp : "/tmp") + "/lw-fuzz-XXXXXX";
    if (!mkdtemp(tmpl.data())) Fail("cannot create a scratch directory under " + tmpl);
    static const std::string keep = tmpl;
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(keep, ec);
    });
    return std::filesystem::path(tmpl);
  }();
  return dir;
}

/// Writes `bytes` to `path` (creating parent folders), replacing what was there. False when the
/// path cannot be a file (e.g. a folder of that name was written before).
inline bool WriteFile(const std::filesystem::path& path, std::string_view bytes) {
  std::error_code ec;
  std::filesystem::create_directories(path.parent_path(), ec);
  if (ec || std::filesystem::is_directory(path, ec)) return false;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return static_cast<bool>(out);
}

/// 2026-06-01T00:00:00Z: "now" of the targets that validate readings.
inline constexpr int64_t kNowS = 1780272000;

}  // namespace lw::fuzz
