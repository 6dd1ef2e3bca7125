#pragma once
// Integration-test helpers: a child process that is always cleaned up, and a real mosquitto broker
// on a free 127.0.0.1 port with its config (and optional persistence) in a temp dir.
//
//   lw::test::MosquittoFixture broker({.persistence = true});
//   broker.Start();                 // throws std::runtime_error with the reason (and log tail)
//   ... connect to broker.uri() ...
//   broker.Stop();  broker.Start(); // same port, same persistence dir
//   // destructor: kills the broker, removes the temp dir
//
// Children get PR_SET_PDEATHSIG(SIGKILL): if the test binary dies, they die too.
#include <sys/types.h>

#include <chrono>
#include <string>
#include <utility>
#include <vector>

#include "support/temp_directory.hpp"

namespace lw::test {

/// One child process (fork + exec), stdout and stderr appended to a log file.
class ChildProcess {
 public:
  ChildProcess() = default;
  ~ChildProcess() { Kill(); }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  /// Starts argv[0] (searched in PATH when it has no '/'). Throws std::runtime_error.
  void Start(const std::vector<std::string>& argv, const std::string& log_file);
  /// True while the child has not exited (reaps it when it has).
  bool Running();
  /// Sends `signal`, waits up to `timeout`, then SIGKILLs. Returns the wait status (-1: none).
  /// 60 s: a program's clean exit (final messages, spool and database closed) takes well under a
  /// second, but a starved one on a loaded machine can take seconds; only a hang reaches the kill.
  int Stop(int signal, std::chrono::milliseconds timeout = std::chrono::seconds(60));
  /// SIGKILL and reap. No-op when not running.
  void Kill();
  /// Sends `signal` and returns at once (no reaping): to hit several children at the same instant.
  void Signal(int signal);
  /// Waits up to `timeout` for the child to exit by itself; returns its exit code, or -1 when it
  /// was killed (after the timeout) or died by a signal.
  int Wait(std::chrono::milliseconds timeout = std::chrono::seconds(120));
  pid_t pid() const { return pid_; }
  /// Wait status after the child exited (from waitpid), -1 before.
  int status() const { return status_; }

 private:
  pid_t pid_ = -1;
  int status_ = -1;
};

/// A free TCP port on 127.0.0.1 (bound and released; there is a small race, as with any such helper).
int FreeLoopbackPort();

/// True when a TCP connection to 127.0.0.1:port succeeds.
bool PortAccepts(int port);

/// Last `max_bytes` of a text file ("" when missing), for failure messages.
std::string FileTail(const std::string& path, size_t max_bytes = 2000);

/// Runs a command to completion (output appended to `log_file`); returns its exit code, -1 when it
/// did not finish within 120 s (a generous bound: only a hang reaches it) or died by a signal.
int RunCommand(const std::vector<std::string>& argv, const std::string& log_file);

/// The broker binary: $LW_MOSQUITTO, else /usr/sbin/mosquitto, else "mosquitto" on PATH.
/// (mosquitto_passwd and openssl are looked up on PATH.)
std::string MosquittoBinary();

class MosquittoFixture {
 public:
  struct Options {
    bool persistence = false;  ///< persistence true + autosave every second in the temp dir
    /// TLS listener: a throw-away CA and a server certificate for 127.0.0.1 are made with the
    /// openssl CLI in the temp dir; clients trust ca_file(). uri() becomes ssl://.
    bool tls = false;
    /// When set, clients must log in with these (password file made with mosquitto_passwd).
    std::string username;
    std::string password;
    std::string extra_config;  ///< appended to mosquitto.conf verbatim
  };
  /// Several accounts and an ACL (kept out of Options, which callers fill by designated
  /// initializers).
  struct Access {
    /// More accounts in the same password file (needs Options::username): {user, password}.
    std::vector<std::pair<std::string, std::string>> more_users;
    /// When set, mosquitto enforces this ACL file (e.g. packaging/mosquitto/linerwatch.acl).
    std::string acl_file;
  };
  MosquittoFixture() : MosquittoFixture(Options{}) {}
  explicit MosquittoFixture(Options options, Access access = {});
  ~MosquittoFixture();
  MosquittoFixture(const MosquittoFixture&) = delete;
  MosquittoFixture& operator=(const MosquittoFixture&) = delete;

  /// Starts mosquitto and waits (up to 60 s) until the port accepts connections. Throws
  /// std::runtime_error with the log tail on failure.
  void Start();
  /// SIGTERM (mosquitto saves its persistence database) and wait.
  void Stop();
  /// SIGKILL: an abrupt broker death (nothing saved since the last autosave).
  void Kill();
  /// Sends `signal` to the broker and returns at once (Kill() then reaps it).
  void Signal(int signal) { process_.Signal(signal); }
  void Restart() {
    Stop();
    Start();
  }
  bool running() { return process_.Running(); }

  int port() const { return port_; }
  /// The broker's process id (-1 when not started; for CPU accounting in benchmarks).
  pid_t pid() const { return process_.pid(); }
  /// "tcp://127.0.0.1:PORT" ("ssl://..." with tls).
  std::string uri() const;
  /// The CA certificate clients trust (tls only).
  std::string ca_file() const { return dir_.File("ca.pem"); }
  /// The temp dir holding mosquitto.conf, mosquitto.log and the persistence database.
  const std::filesystem::path& dir() const { return dir_.path(); }
  std::string log_file() const { return dir_.File("mosquitto.log"); }

 private:
  Options options_;
  TempDirectory dir_;
  int port_;
  ChildProcess process_;
};

}  // namespace lw::test
