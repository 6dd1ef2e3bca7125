// The tokens file (--tokens): what is accepted and how a bad file is named.
#include <fstream>

#include "server/auth.hpp"
#include "support/mosquitto_fixture.hpp"

#include <CppUTest/TestHarness.h>

using lw::server::TokenStore;

namespace {
std::string ErrorOf(const std::filesystem::path& file) {
  try {
    TokenStore::Load(file);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST_GROUP(Tokens) {
  lw::test::TempDirectory dir{"lw-auth-test"};
};

TEST(Tokens, HashesAndScopesLoad) {
  // sha256("secret")
  std::ofstream(dir.File("t.json")) << R"({"tokens": [{"name": "ops", "scopes": ["read", "write"],
      "sha256": "2BB80D537B1DA3E38BD30361AA855686BDE0EACD7162FEF6A25FE97BF527A25B"}]})";
  const TokenStore tokens = TokenStore::Load(dir.File("t.json"));
  CHECK(tokens.enabled());
  const auto t = tokens.Check("secret");
  CHECK(t.has_value() && t->read && t->write);
  CHECK_FALSE(tokens.Check("secreT").has_value());
}

// Found by fuzz/ (fuzz_config): a number beyond double range made nlohmann::json throw
// out_of_range (not parse_error), which escaped Load instead of an error naming --tokens.
TEST(Tokens, NumberBeyondDoubleRangeIsNamed) {
  std::ofstream(dir.File("t.json")) << R"({"tokens": [], "version": 1e999})";
  const std::string e = ErrorOf(dir.File("t.json"));
  CHECK_TEXT(e.find("--tokens") != std::string::npos && e.find("not valid JSON") != std::string::npos, e.c_str());
}
