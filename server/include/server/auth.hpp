#pragma once
/// Bearer tokens for the REST API. The tokens file holds only SHA-256 hashes:
/// {"tokens": [{"name": "ops", "sha256": "<64 hex>", "scopes": ["read", "write"]}]}
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace lw::server {

struct Token {
  std::string name;
  std::string sha256;
  bool read = false;
  bool write = false;
};

class TokenStore {
 public:
  TokenStore() = default;  ///< no tokens: the API is open (a trusted network)
  /// Throws std::runtime_error naming the file and the rule broken.
  static TokenStore Load(const std::filesystem::path& path);
  bool enabled() const { return enabled_; }
  /// The token whose hash matches `bearer`, or nullopt. Constant-time comparison per token.
  std::optional<Token> Check(const std::string& bearer) const;
  void Add(Token t) {
    tokens_.push_back(std::move(t));
    enabled_ = true;
  }

 private:
  bool enabled_ = false;
  std::vector<Token> tokens_;
};

}  // namespace lw::server
