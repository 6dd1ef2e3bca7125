#include "core/hmac.hpp"

#include "core/wear_map.hpp"

#include <openssl/evp.h>
#include <openssl/hmac.h>

#include <cstdio>
#include <stdexcept>

namespace lw::core {
namespace {

std::string Hex(const unsigned char* digest, unsigned len) {
  std::string hex;
  char b[3];
  for (unsigned i = 0; i < len; ++i) {
    std::snprintf(b, sizeof b, "%02x", digest[i]);
    hex += b;
  }
  return hex;
}

}  // namespace

// Beside the HMAC so both digests share one hex encoding (declared in core/wear_map.hpp, whose
// maps it fingerprints).
std::string Sha256Hex(const std::string& bytes) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  EVP_Digest(bytes.data(), bytes.size(), digest, &len, EVP_sha256(), nullptr);
  return Hex(digest, len);
}

std::string HmacSha256Hex(const std::string& key, const std::string& message) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  // OpenSSL's one-shot HMAC with the SHA-256 Sha256Hex uses (libcrypto is already linked for it).
  if (!HMAC(EVP_sha256(), key.data(), static_cast<int>(key.size()), reinterpret_cast<const unsigned char*>(message.data()),
            message.size(), digest, &len)) {
    throw std::runtime_error("HMAC-SHA256 failed (OpenSSL)");
  }
  return Hex(digest, len);
}

}  // namespace lw::core
