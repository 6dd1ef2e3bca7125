#pragma once
// A folder that one child process sees mounted read-only: the child runs in a mount namespace of its
// own (util-linux unshare) in which the folder is bind-mounted on itself and remounted read-only;
// the test and the rest of the machine still read and write it. As root, a plain mount namespace;
// otherwise a user namespace mapping the caller to root. Where both are refused (a container
// without CAP_SYS_ADMIN, user namespaces switched off), Available() says why and the test skips.
#include <string>
#include <vector>

#include "support/mosquitto_fixture.hpp"

namespace lw::test {

class ReadOnlyMount {
 public:
  /// Exit code of a test program that skips (ctest's SKIP_RETURN_CODE of lw_add_skipped_test).
  static constexpr int kSkip = 77;

  /// `dir` must exist; `log` receives the probe's output.
  ReadOnlyMount(std::string dir, const std::string& log) : dir_(std::move(dir)) {
    // The probe: inside, creating a file in the folder must fail with the read-only reason.
    const std::string probe = "! touch '" + dir_ + "/.rw-probe' 2>/dev/null";
    for (const std::vector<std::string>& prefix :
         {std::vector<std::string>{"unshare", "--mount", "--propagation", "private"},
          std::vector<std::string>{"unshare", "--map-root-user", "--mount", "--propagation", "private"}}) {
      prefix_ = prefix;
      if (RunCommand(Command({"sh", "-c", probe}), log) == 0) return;
    }
    prefix_.clear();
    why_ = "no mount namespace with a read-only bind mount here (unshare refused: " + FileTail(log, 400) + ")";
  }

  /// Empty when the folder can be made read-only for a child; else why not.
  const std::string& Unavailable() const { return why_; }

  /// `argv` run with the folder read-only: unshare execs sh, which mounts and execs argv[0], so the
  /// child process is the program itself (signals reach it).
  std::vector<std::string> Command(const std::vector<std::string>& argv) const {
    std::vector<std::string> out = prefix_;
    for (const char* a : {"sh", "-c", "mount --bind \"$0\" \"$0\" && mount -o remount,bind,ro \"$0\" && exec \"$@\""})
      out.push_back(a);
    out.push_back(dir_);
    out.insert(out.end(), argv.begin(), argv.end());
    return out;
  }

 private:
  std::string dir_;
  std::vector<std::string> prefix_;
  std::string why_;
};

}  // namespace lw::test
