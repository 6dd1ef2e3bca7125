#pragma once
// Prometheus' own parser and linter on a scrape: `promtool check metrics` (Debian's package
// prometheus, which scripts/install-deps installs).
#include <stdio.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <string>

namespace lw::test {

/// "" when `promtool CHECK FILE` (CHECK: "check metrics < " reads stdin, "check rules " a file
/// argument) accepts `text` written to a temporary file named with `suffix`; otherwise what it
/// said, or why it could not run.
inline std::string RunPromtool(const std::string& check, const std::string& text, const std::string& suffix = "") {
  std::string path = "/tmp/lw-promtool-XXXXXX" + suffix;
  const int fd = ::mkstemps(path.data(), static_cast<int>(suffix.size()));
  if (fd < 0) return "cannot create a temporary file";
  const bool written = ::write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size());
  ::close(fd);
  if (!written) {
    ::unlink(path.c_str());
    return "cannot write a temporary file";
  }
  const std::string command = "promtool " + check + path + " 2>&1";
  FILE* p = ::popen(command.c_str(), "r");
  std::string said;
  char buf[512];
  while (p && ::fgets(buf, sizeof buf, p)) said += buf;
  const int status = p ? ::pclose(p) : -1;
  ::unlink(path.c_str());
  if (status == 0) return {};
  if (WIFEXITED(status) && WEXITSTATUS(status) == 127)
    return "promtool not found: scripts/install-deps installs Debian's prometheus package, which has it";
  return "promtool " + check.substr(0, check.find_last_not_of(" <") + 1) + " failed (status " + std::to_string(status) +
         "): " + said;
}

/// "" when `promtool check metrics` accepts `text` (parse and lint); otherwise what it said, or
/// why it could not run.
inline std::string PromtoolCheck(const std::string& text) {
  return RunPromtool("check metrics < ", text);
}

}  // namespace lw::test
