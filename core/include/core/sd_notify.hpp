#pragma once
// Readiness for systemd (Type=notify) without libsystemd: the sd_notify(3) protocol is one datagram
// to the AF_UNIX socket named by $NOTIFY_SOCKET (a leading '@' means the abstract namespace).
// Header-only: the gateway uses it without linking lw_core.
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <string>

namespace lw::core {

/// Sends `state` (e.g. "READY=1", "STOPPING=1") to the service manager. Returns false, doing
/// nothing, when $NOTIFY_SOCKET is unset (not started by systemd with Type=notify), and when the
/// socket cannot be reached; never throws, never blocks.
inline bool SdNotify(const std::string& state) {
  const char* path = std::getenv("NOTIFY_SOCKET");
  if (path == nullptr || path[0] == '\0') return false;
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  const size_t len = std::strlen(path);
  if (len >= sizeof addr.sun_path) return false;
  std::memcpy(addr.sun_path, path, len);
  if (addr.sun_path[0] == '@') addr.sun_path[0] = '\0';
  const int fd = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (fd < 0) return false;
  const auto addr_len = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + len);
  const ssize_t sent = ::sendto(fd, state.data(), state.size(), MSG_NOSIGNAL, reinterpret_cast<const sockaddr*>(&addr), addr_len);
  ::close(fd);
  return sent == static_cast<ssize_t>(state.size());
}

}  // namespace lw::core
