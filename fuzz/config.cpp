// Configuration files: the same bytes as the --config FILE of the host programs (core's shared
// command line, linerwatch-server's options, linerwatch-gateway's options) and as the server's
// --tokens file.
// Properties: a bad file is refused with the documented error type only (core::UsageError,
// gateway::ConfigError, std::runtime_error for tokens) naming --config/--tokens; nothing else is
// thrown, nothing crashes.
#include <map>
#include <string>

#include "core/cmdline.hpp"
#include "fuzz_support.hpp"
#include "gateway/config.hpp"
#include "server/auth.hpp"
#include "server/server.hpp"

using namespace lw;
using lw::fuzz::Check;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::filesystem::path file = fuzz::ScratchDir() / "config.json";
  if (!fuzz::WriteFile(file, std::string_view(reinterpret_cast<const char*>(data), size))) fuzz::Fail("cannot write " + file.string());
  const std::string path = file.string();

  std::map<std::string, std::string> applied;
  try {
    core::ParseCommandLine({"--config", path}, {}, [&](const std::string& k, const std::string& v) { applied[k] = v; });
  } catch (const core::UsageError& e) {
    Check(std::string(e.what()).find("--config") != std::string::npos, std::string("UsageError not naming --config: ") + e.what());
  }
  try {
    (void)server::ParseServerOptions({"--config", path});
  } catch (const core::UsageError&) {
  }
  try {
    gateway::Config config;
    (void)gateway::ParseCommandLine({"linerwatch-gateway", "--config", path}, &config);
  } catch (const gateway::ConfigError&) {
  }
  try {
    const server::TokenStore tokens = server::TokenStore::Load(file);
    (void)tokens.Check("secret");
  } catch (const std::runtime_error& e) {
    Check(std::string(e.what()).find("--tokens") != std::string::npos, std::string("tokens error not naming --tokens: ") + e.what());
  }
  return 0;
}
