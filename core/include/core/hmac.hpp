#pragma once
/// HMAC-SHA256 (RFC 2104 over SHA-256, the digest of core::Sha256Hex): the signature of the
/// server's webhook notifications (docs/alarms.md, *Notifications*).
#include <string>

namespace lw::core {

/// HMAC-SHA256 of `message` under `key`, as 64 lower-case hex digits (RFC 4231's test vectors).
std::string HmacSha256Hex(const std::string& key, const std::string& message);

}  // namespace lw::core
