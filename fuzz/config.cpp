// Configuration files: the same bytes as the --config FILE of the host programs (core's shared
// command line, linerwatch-server's options, linerwatch-gateway's options) and as the server's
// --tokens file.
// Properties: a bad file is refused with the documented error type only (core::ConfigFileError
// naming the file, core::UsageError, gateway::ConfigError, std::runtime_error for tokens naming
// --tokens); nothing else is thrown, nothing crashes.
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
  if (!fuzz::WriteFile(file, std::string_view(reinterpret_cast<const char*>(data), size)))
    fuzz::Fail("cannot write " + file.string());
  const std::string path = file.string();

  // Every option type of core's parser, repeatable and positional included, and unknown keys kept.
  static const core::OptionTable table(
      {core::Option::Text("name", "S", "text"), core::Option::Whole("count", "N", -5, 1000, "whole"),
       core::Option::Unsigned("seed", "N", "seed"),
       core::Option::Number("rate", "X", core::NumberRange{0, 1, false, true}, "number"), core::Option::Switch("quiet", "switch"),
       core::Option::Text("effect", "E", "list").Repeatable()},
      "BUNDLE", "bundle", /*keep_other_config_keys=*/true);
  try {
    const core::ParsedOptions o = core::ParseOptions(table, {"--config", path});
    (void)o.Integer<int>("count", 0);
    (void)o.Integer<uint64_t>("seed", 0);
    (void)o.Number("rate", 0);
    (void)o.Switch("quiet");
    (void)o.Texts("effect");
  } catch (const core::ConfigFileError& e) {
    Check(std::string(e.what()).rfind("config " + path, 0) == 0, std::string("ConfigFileError not naming the file: ") + e.what());
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
    Check(std::string(e.what()).find("--tokens") != std::string::npos,
          std::string("tokens error not naming --tokens: ") + e.what());
  }
  return 0;
}
