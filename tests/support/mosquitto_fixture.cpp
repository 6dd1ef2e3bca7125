#include "support/mosquitto_fixture.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <pwd.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <utility>

namespace lw::test {

void ChildProcess::Start(const std::vector<std::string>& argv, const std::string& log_file) {
  if (pid_ > 0 && Running()) throw std::runtime_error("ChildProcess::Start: already running");
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(127);  // the parent died before prctl
    const int fd = open(log_file.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    if (fd >= 0) {
      dup2(fd, STDOUT_FILENO);
      dup2(fd, STDERR_FILENO);
      close(fd);
    }
    const int devnull = open("/dev/null", O_RDONLY);
    if (devnull >= 0) dup2(devnull, STDIN_FILENO);
    execvp(args[0], args.data());
    _exit(127);
  }
  pid_ = pid;
  status_ = -1;
}

bool ChildProcess::Running() {
  if (pid_ <= 0) return false;
  int st = 0;
  const pid_t r = waitpid(pid_, &st, WNOHANG);
  if (r == pid_) {
    status_ = st;
    pid_ = -1;
    return false;
  }
  return true;
}

int ChildProcess::Stop(int signal, std::chrono::milliseconds timeout) {
  if (!Running()) return status_;
  kill(pid_, signal);
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (!Running()) return status_;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  kill(pid_, SIGKILL);
  int st = 0;
  waitpid(pid_, &st, 0);
  status_ = st;
  pid_ = -1;
  return status_;
}

void ChildProcess::Kill() {
  Stop(SIGKILL);
}

void ChildProcess::Signal(int signal) {
  if (pid_ > 0) kill(pid_, signal);
}

int ChildProcess::Wait(std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (Running()) {
    if (std::chrono::steady_clock::now() >= deadline) {
      Kill();
      return -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return WIFEXITED(status_) ? WEXITSTATUS(status_) : -1;
}

int RunCommand(const std::vector<std::string>& argv, const std::string& log_file) {
  ChildProcess p;
  p.Start(argv, log_file);
  return p.Wait();
}

int FreeLoopbackPort() {
  const int s = socket(AF_INET, SOCK_STREAM, 0);
  if (s < 0) throw std::runtime_error("socket failed");
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = 0;
  socklen_t len = sizeof a;
  if (bind(s, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || getsockname(s, reinterpret_cast<sockaddr*>(&a), &len) != 0) {
    close(s);
    throw std::runtime_error("cannot bind a loopback port");
  }
  close(s);
  return ntohs(a.sin_port);
}

bool PortAccepts(int port) {
  const int s = socket(AF_INET, SOCK_STREAM, 0);
  if (s < 0) return false;
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(static_cast<uint16_t>(port));
  const bool ok = connect(s, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  close(s);
  return ok;
}

std::string FileTail(const std::string& path, size_t max_bytes) {
  std::ifstream in(path);
  if (!in) return "";
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string s = ss.str();
  return s.size() > max_bytes ? s.substr(s.size() - max_bytes) : s;
}

std::string MosquittoBinary() {
  if (const char* env = std::getenv("LW_MOSQUITTO"); env && *env) return env;
  if (access("/usr/sbin/mosquitto", X_OK) == 0) return "/usr/sbin/mosquitto";
  return "mosquitto";
}

MosquittoFixture::MosquittoFixture(Options options, Access access)
    : options_(std::move(options)), dir_("lw-mosquitto"), port_(FreeLoopbackPort()) {
  const std::string setup_log = dir_.File("setup.log");
  auto run = [&](const std::vector<std::string>& argv) {
    if (RunCommand(argv, setup_log) != 0) {
      throw std::runtime_error("MosquittoFixture: '" + argv[0] + " " + argv[1] + "' failed: " + FileTail(setup_log));
    }
  };
  std::ofstream conf(dir_.File("mosquitto.conf"));
  conf << "listener " << port_ << " 127.0.0.1\n";
  if (options_.tls) {
    const std::string d = dir_.path().string() + "/";
    std::ofstream(d + "san.ext") << "subjectAltName=IP:127.0.0.1,DNS:localhost\n";
    run({"openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes", "-keyout",
         d + "ca.key", "-out", d + "ca.pem", "-days", "2", "-subj", "/CN=linerwatch test CA"});
    run({"openssl", "req", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes", "-keyout", d + "server.key",
         "-out", d + "server.csr", "-subj", "/CN=127.0.0.1"});
    run({"openssl", "x509", "-req", "-in", d + "server.csr", "-CA", d + "ca.pem", "-CAkey", d + "ca.key", "-CAcreateserial",
         "-out", d + "server.pem", "-days", "2", "-extfile", d + "san.ext"});
    conf << "cafile " << d << "ca.pem\ncertfile " << d << "server.pem\nkeyfile " << d << "server.key\n";
  }
  if (!options_.username.empty()) {
    run({"mosquitto_passwd", "-b", "-c", dir_.File("passwords"), options_.username, options_.password});
    for (const auto& [user, password] : access.more_users) {
      run({"mosquitto_passwd", "-b", dir_.File("passwords"), user, password});
    }
    conf << "allow_anonymous false\npassword_file " << dir_.File("passwords") << "\n";
  } else {
    conf << "allow_anonymous true\n";
  }
  conf << "log_dest stderr\n"
       << "log_type error\nlog_type warning\nlog_type notice\n";
  // Started as root, mosquitto would switch to user "mosquitto", who cannot write our temp dir.
  if (const passwd* pw = getpwuid(geteuid())) conf << "user " << pw->pw_name << "\n";
  if (options_.persistence) {
    conf << "persistence true\n"
         << "persistence_location " << dir_.path().string() << "/\n"
         << "autosave_interval 1\n";
  } else {
    conf << "persistence false\n";
  }
  if (!access.acl_file.empty()) conf << "acl_file " << access.acl_file << "\n";
  conf << options_.extra_config << "\n";
}

MosquittoFixture::~MosquittoFixture() {
  process_.Kill();
}

std::string MosquittoFixture::uri() const {
  return (options_.tls ? "ssl://127.0.0.1:" : "tcp://127.0.0.1:") + std::to_string(port_);
}

void MosquittoFixture::Start() {
  if (process_.Running()) return;
  process_.Start({MosquittoBinary(), "-c", dir_.File("mosquitto.conf")}, log_file());
  // 60 s: a healthy start takes milliseconds, but on a loaded 2-core CI machine (a debootstrap
  // beside the tests) 5 s was once not enough; only a broker that never listens reaches this.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  int retries = 0;
  while (std::chrono::steady_clock::now() < deadline) {
    if (!process_.Running()) {
      // The port can be briefly taken on a restart (a client's connect to the dead port may even
      // get it as its own source port): try again a few times before giving up.
      if (retries++ < 5 && FileTail(log_file(), 300).find("in use") != std::string::npos) {
        std::this_thread::sleep_for(std::chrono::milliseconds(200));
        process_.Start({MosquittoBinary(), "-c", dir_.File("mosquitto.conf")}, log_file());
        continue;
      }
      throw std::runtime_error("mosquitto exited on start (port " + std::to_string(port_) + "): " + FileTail(log_file()));
    }
    if (PortAccepts(port_)) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  process_.Kill();
  throw std::runtime_error("mosquitto did not accept connections on port " + std::to_string(port_) +
                           " within 60 s: " + FileTail(log_file()));
}

void MosquittoFixture::Stop() {
  process_.Stop(SIGTERM);
}

void MosquittoFixture::Kill() {
  process_.Kill();
}

}  // namespace lw::test
