#include <csignal>
#include <iostream>

#include "core/cmdline.hpp"
#include "server/server.hpp"

namespace {
std::atomic<bool> g_stop{false};
void OnSignal(int) {
  g_stop = true;
}
}  // namespace

int main(int argc, char** argv) {
  lw::server::ServerOptions options;
  try {
    options = lw::server::ParseServerOptions(std::vector<std::string>(argv + 1, argv + argc));
  } catch (const std::exception& e) {
    std::cerr << "linerwatch-server: " << e.what() << "\n";
    return 2;
  }
  if (options.help) {
    std::cout << lw::server::ServerHelp();
    return 0;
  }
  struct sigaction sa {};
  sa.sa_handler = OnSignal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  std::signal(SIGPIPE, SIG_IGN);
  try {
    lw::server::RunServer(options, g_stop, std::cerr);
  } catch (const std::exception& e) {
    std::cerr << "linerwatch-server: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
