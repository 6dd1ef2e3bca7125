// core::HmacSha256Hex against RFC 4231's HMAC-SHA256 test vectors (cases 1-4, 6, 7; case 5 is a
// truncated output).
#include "core/hmac.hpp"

#include <string>

#include <CppUTest/TestHarness.h>  // last

namespace {
std::string Bytes(size_t n, char c) {
  return std::string(n, c);
}
}  // namespace

TEST_GROUP(Hmac){};

TEST(Hmac, Rfc4231Case1ShortKey) {
  STRCMP_EQUAL("b0344c61d8db38535ca8afceaf0bf12b881dc200c9833da726e9376c2e32cff7",
               lw::core::HmacSha256Hex(Bytes(20, '\x0b'), "Hi There").c_str());
}

TEST(Hmac, Rfc4231Case2KeyShorterThanTheOutput) {
  STRCMP_EQUAL("5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843",
               lw::core::HmacSha256Hex("Jefe", "what do ya want for nothing?").c_str());
}

TEST(Hmac, Rfc4231Case3CombinedLengthAboveABlock) {
  STRCMP_EQUAL("773ea91e36800e46854db8ebd09181a72959098b3ef8c122d9635514ced565fe",
               lw::core::HmacSha256Hex(Bytes(20, '\xaa'), Bytes(50, '\xdd')).c_str());
}

TEST(Hmac, Rfc4231Case4) {
  std::string key;
  for (int i = 1; i <= 25; ++i) key += static_cast<char>(i);
  STRCMP_EQUAL("82558a389a443c0ea4cc819899f2083a85f0faa3e578f8077a2e3ff46729665b",
               lw::core::HmacSha256Hex(key, Bytes(50, '\xcd')).c_str());
}

TEST(Hmac, Rfc4231Case6KeyLargerThanABlockIsHashedFirst) {
  STRCMP_EQUAL("60e431591ee0b67f0d8a26aacbf5b77f8e0bc6213728c5140546040f0ee37f54",
               lw::core::HmacSha256Hex(Bytes(131, '\xaa'), "Test Using Larger Than Block-Size Key - Hash Key First").c_str());
}

TEST(Hmac, Rfc4231Case7KeyAndDataLargerThanABlock) {
  STRCMP_EQUAL("9b09ffa71b942fcb27635fbcd5b0e944bfdc63644f0713938a7f51535c3a35e2",
               lw::core::HmacSha256Hex(Bytes(131, '\xaa'),
                                       "This is a test using a larger than block-size key and a larger than block-size data. "
                                       "The key needs to be hashed before being used by the HMAC algorithm.")
                   .c_str());
}

TEST(Hmac, EmptyKeyAndMessage) {
  // The well-known HMAC-SHA256("", ""), so an empty secret is not mistaken for "no signature".
  STRCMP_EQUAL("b613679a0814d9ec772f95d778c35fc5ff1697c493715653c6c712144292c5ad", lw::core::HmacSha256Hex("", "").c_str());
}
