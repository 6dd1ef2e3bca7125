// SdNotify: the sd_notify(3) datagram reaches a socket named by $NOTIFY_SOCKET (a path, or '@'
// for the abstract namespace); without the variable nothing is sent.
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <string>

#include "core/sd_notify.hpp"

#include <CppUTest/TestHarness.h>  // last

namespace {

// A datagram socket bound to `name` (abstract when it starts with '@'), as systemd's.
class ManagerSocket {
 public:
  explicit ManagerSocket(const std::string& name) : name_(name) {
    fd_ = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::memcpy(a.sun_path, name.data(), name.size());
    if (name[0] == '@')
      a.sun_path[0] = '\0';
    else
      unlink(name.c_str());
    bound_ =
        bind(fd_, reinterpret_cast<sockaddr*>(&a), static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + name.size())) == 0;
    timeval tv{2, 0};
    setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  }
  ~ManagerSocket() {
    close(fd_);
    if (name_[0] != '@') unlink(name_.c_str());
  }
  bool bound() const { return bound_; }
  std::string Receive() {
    char buf[256];
    const ssize_t n = recv(fd_, buf, sizeof buf, 0);
    return n > 0 ? std::string(buf, static_cast<size_t>(n)) : std::string();
  }

 private:
  std::string name_;
  int fd_ = -1;
  bool bound_ = false;
};

}  // namespace

TEST_GROUP(SdNotify){void teardown() override{unsetenv("NOTIFY_SOCKET");
}
}
;

TEST(SdNotify, ReadyReachesThePathSocket) {
  const std::string path = "/tmp/lw-sd-notify-" + std::to_string(getpid());
  ManagerSocket manager(path);
  CHECK_TRUE(manager.bound());
  setenv("NOTIFY_SOCKET", path.c_str(), 1);
  CHECK_TRUE(lw::core::SdNotify("READY=1"));
  STRCMP_EQUAL("READY=1", manager.Receive().c_str());
}

TEST(SdNotify, AnAbstractSocketIsNamedWithAnAt) {
  const std::string name = "@lw-sd-notify-" + std::to_string(getpid());
  ManagerSocket manager(name);
  CHECK_TRUE(manager.bound());
  setenv("NOTIFY_SOCKET", name.c_str(), 1);
  CHECK_TRUE(lw::core::SdNotify("STOPPING=1"));
  STRCMP_EQUAL("STOPPING=1", manager.Receive().c_str());
}

TEST(SdNotify, WithoutNotifySocketNothingIsSent) {
  unsetenv("NOTIFY_SOCKET");
  CHECK_FALSE(lw::core::SdNotify("READY=1"));
  setenv("NOTIFY_SOCKET", "/nonexistent/lw-notify", 1);
  CHECK_FALSE(lw::core::SdNotify("READY=1"));
}
