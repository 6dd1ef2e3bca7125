#pragma once
// Prometheus' own parser and linter on a scrape: `promtool check metrics` (Debian's package
// prometheus, which scripts/install-deps installs).
#include <stdio.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <string>

namespace lw::test {

/// "" when `promtool check metrics` accepts `text` (parse and lint); otherwise what it said, or
/// why it could not run.
inline std::string PromtoolCheck(const std::string& text) {
  char path[] = "/tmp/lw-promtool-XXXXXX";
  const int fd = ::mkstemp(path);
  if (fd < 0) return "cannot create a temporary file";
  const bool written = ::write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size());
  ::close(fd);
  if (!written) {
    ::unlink(path);
    return "cannot write a temporary file";
  }
  const std::string command = std::string("promtool check metrics < ") + path + " 2>&1";
  FILE* p = ::popen(command.c_str(), "r");
  std::string said;
  char buf[512];
  while (p && ::fgets(buf, sizeof buf, p)) said += buf;
  const int status = p ? ::pclose(p) : -1;
  ::unlink(path);
  if (status == 0) return {};
  if (WIFEXITED(status) && WEXITSTATUS(status) == 127)
    return "promtool not found: scripts/install-deps installs Debian's prometheus package, which has it";
  return "promtool check metrics failed (status " + std::to_string(status) + "): " + said;
}

}  // namespace lw::test
