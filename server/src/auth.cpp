#include "server/auth.hpp"

#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "core/wear_map.hpp"

namespace lw::server {

TokenStore TokenStore::Load(const std::filesystem::path& path) {
  const std::string where = "--tokens '" + path.string() + "': ";
  std::ifstream in(path);
  if (!in) throw std::runtime_error(where + "cannot read the file");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    throw std::runtime_error(where + "not valid JSON: " + e.what());
  } catch (const nlohmann::json::exception& e) {  // a number out of range (1e999) is not a parse_error
    throw std::runtime_error(where + "not valid JSON: " + e.what());
  }
  if (!j.is_object() || !j.contains("tokens") || !j["tokens"].is_array()) {
    throw std::runtime_error(where + "must hold {\"tokens\": [...]}");
  }
  TokenStore store;
  store.enabled_ = true;  // a tokens file with no entries locks the API
  size_t index = 0;
  for (const auto& t : j["tokens"]) {
    const std::string item = where + "tokens[" + std::to_string(index++) + "]: ";
    if (!t.is_object()) throw std::runtime_error(item + "must be an object");
    Token tok;
    tok.name = t.value("name", std::string("token") + std::to_string(index));
    if (!t.contains("sha256") || !t["sha256"].is_string())
      throw std::runtime_error(item + "needs \"sha256\" (hex SHA-256 of the token)");
    tok.sha256 = t["sha256"].get<std::string>();
    for (auto& ch : tok.sha256) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    if (tok.sha256.size() != 64 || tok.sha256.find_first_not_of("0123456789abcdef") != std::string::npos) {
      throw std::runtime_error(item + "\"sha256\" must be 64 hex digits (printf %s TOKEN | sha256sum)");
    }
    if (t.contains("token")) throw std::runtime_error(item + "holds a plain \"token\": store only its sha256");
    if (!t.contains("scopes") || !t["scopes"].is_array())
      throw std::runtime_error(item + "needs \"scopes\": [\"read\"] or [\"read\", \"write\"]");
    for (const auto& s : t["scopes"]) {
      if (s == "read")
        tok.read = true;
      else if (s == "write")
        tok.write = true;
      else
        throw std::runtime_error(item + "unknown scope " + s.dump() + " (read, write)");
    }
    store.tokens_.push_back(tok);
  }
  return store;
}

std::optional<Token> TokenStore::Check(const std::string& bearer) const {
  if (bearer.empty()) return std::nullopt;
  const std::string h = core::Sha256Hex(bearer);
  for (const Token& t : tokens_) {
    unsigned diff = 0;
    for (size_t i = 0; i < 64; ++i) diff |= static_cast<unsigned>(h[i] ^ t.sha256[i]);
    if (diff == 0) return t;
  }
  return std::nullopt;
}

}  // namespace lw::server
