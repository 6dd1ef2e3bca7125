#pragma once
// The receivers of the server's alarm notifications in tests (docs/alarms.md, *Notifications*): a
// webhook receiver (cpp-httplib in the test process) that records each POST and answers the status
// it is told, and a real SMTP sink (Debian's python3-aiosmtpd, its Mailbox handler writing each
// message into a maildir).
//
//   lw::test::WebhookReceiver hook;      hook.Start();   hook.url()  -> http://127.0.0.1:P/hook
//   lw::test::SmtpSink smtp(dir);        smtp.Start();   smtp.url()  -> smtp://127.0.0.1:Q
//   lw::test::SmtpSink tls(dir, 0, {cert, key});  a sink that refuses MAIL before STARTTLS
//                                                 (tests/support/smtp_tls_sink.py, LW_SMTP_TLS_SINK)
#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "support/mosquitto_fixture.hpp"

#include <httplib.h>  // after Eigen (<resolv.h> defines _res)

namespace lw::test {

class WebhookReceiver {
 public:
  struct Post {
    std::map<std::string, std::string> headers;  ///< the X-Linerwatch-* headers and Content-Type
    std::string body;
  };
  /// `port` 0: a free one, kept across Stop() and Start().
  explicit WebhookReceiver(int port = 0) : port_(port == 0 ? FreeLoopbackPort() : port) {}
  ~WebhookReceiver() { Stop(); }
  WebhookReceiver(const WebhookReceiver&) = delete;
  WebhookReceiver& operator=(const WebhookReceiver&) = delete;

  std::string url() const { return "http://127.0.0.1:" + std::to_string(port_) + "/hook"; }
  /// The status every POST is answered with (default 200).
  void Answer(int status) { status_ = status; }

  void Start() {
    server_ = std::make_unique<httplib::Server>();
    server_->Post("/hook", [this](const httplib::Request& req, httplib::Response& res) {
      Post p;
      for (const char* h : {"Content-Type", "X-Linerwatch-Signature", "X-Linerwatch-Event", "X-Linerwatch-Delivery"})
        p.headers[h] = req.get_header_value(h);
      p.body = req.body;
      const int status = status_;
      if (status >= 200 && status < 300) {
        std::lock_guard<std::mutex> lock(mutex_);
        posts_.push_back(std::move(p));
      }
      ++answered_;
      res.status = status;
    });
    if (!server_->bind_to_port("127.0.0.1", port_)) throw std::runtime_error("webhook receiver: port in use");
    thread_ = std::thread([this] { server_->listen_after_bind(); });
    for (int i = 0; i < 200 && !PortAccepts(port_); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  void Stop() {
    if (!server_) return;
    server_->stop();
    if (thread_.joinable()) thread_.join();
    server_.reset();
  }
  /// The POSTs taken (answered 2xx), in order.
  std::vector<Post> Posts() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return posts_;
  }
  /// Every POST answered, whatever its status.
  int answered() const { return answered_; }

 private:
  int port_;
  std::atomic<int> status_{200};
  std::atomic<int> answered_{0};
  std::unique_ptr<httplib::Server> server_;
  std::thread thread_;
  mutable std::mutex mutex_;
  std::vector<Post> posts_;
};

class SmtpSink {
 public:
  /// A certificate and its key (PEM files) for a sink that requires STARTTLS.
  struct Tls {
    std::string cert, key;
  };
  /// The maildir is `dir`/mail; `port` 0: a free one, kept across Stop() and Start(); with `tls`,
  /// MAIL is refused until the client has said STARTTLS.
  explicit SmtpSink(const std::string& dir, int port = 0, std::optional<Tls> tls = std::nullopt)
      : dir_(dir), port_(port == 0 ? FreeLoopbackPort() : port), tls_(std::move(tls)) {
    std::filesystem::create_directories(dir_);
  }
  std::string url() const { return "smtp://127.0.0.1:" + std::to_string(port_); }
  void Start() {
    // Debian's python3-aiosmtpd is installed for the system's python3 (not another one on PATH).
    if (tls_) {
#ifdef LW_SMTP_TLS_SINK
      process_.Start(
          {"/usr/bin/python3", LW_SMTP_TLS_SINK, "127.0.0.1", std::to_string(port_), tls_->cert, tls_->key, dir_ + "/mail"},
          dir_ + "/smtp.log");
#else
      throw std::runtime_error("SMTP sink: this test was built without LW_SMTP_TLS_SINK");
#endif
    } else {
      process_.Start({"/usr/bin/python3", "-m", "aiosmtpd", "-n", "-l", "127.0.0.1:" + std::to_string(port_), "-c",
                      "aiosmtpd.handlers.Mailbox", dir_ + "/mail"},
                     dir_ + "/smtp.log");
    }
    for (int i = 0; i < 300 && !PortAccepts(port_); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (!PortAccepts(port_)) throw std::runtime_error("SMTP sink did not start: " + FileTail(dir_ + "/smtp.log"));
  }
  void Stop() {
    process_.Stop(SIGTERM);
  }
  /// The messages delivered so far, each as received (headers and body).
  std::vector<std::string> Messages() const {
    std::vector<std::string> out;
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator(dir_ + "/mail/new", ec)) {
      std::ifstream in(e.path(), std::ios::binary);
      std::ostringstream text;
      text << in.rdbuf();
      out.push_back(text.str());
    }
    return out;
  }

 private:
  std::string dir_;
  int port_;
  std::optional<Tls> tls_;
  ChildProcess process_;
};

}  // namespace lw::test
