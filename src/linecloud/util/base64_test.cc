#include "linecloud/util/base64.h"

#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <sodium.h>

#include "linecloud/util/error.h"

namespace linecloud {
namespace {

std::string Message(const std::string& text) {
  try {
    Base64Decode(text, "descriptors");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

// libsodium's decoder (the previous implementation) as the reference.
bool SodiumDecode(const std::string& text, std::string* out) {
  out->assign(text.size() / 4 * 3 + 3, '\0');
  size_t len = 0;
  const bool ok =
      sodium_base642bin(reinterpret_cast<unsigned char*>(out->data()), out->size(), text.data(),
                        text.size(), " \n\r", &len, nullptr, sodium_base64_VARIANT_ORIGINAL) == 0;
  out->resize(len);
  return ok;
}

TEST(Base64, RoundTripsEveryLengthAndSkipsWhitespace) {
  std::mt19937 rng(5);
  for (size_t n = 0; n < 70; ++n) {
    std::vector<uint8_t> bytes(n);
    for (auto& b : bytes) b = static_cast<uint8_t>(rng());
    std::string text = Base64Encode(bytes);
    EXPECT_EQ(Base64Decode(text, "x"), std::string(bytes.begin(), bytes.end())) << n;
    for (size_t at = 0; at < text.size(); at += 7) text.insert(at, at % 2 ? "\n" : " \r");
    EXPECT_EQ(Base64Decode(text, "x"), std::string(bytes.begin(), bytes.end())) << n;
  }
}

TEST(Base64, RefusesWhatIsNotBase64NamingTheField) {
  EXPECT_EQ(Message("QUJD*"), "descriptors: not base64");
  EXPECT_EQ(Message("QUJ"), "descriptors: not base64 (length not a multiple of 4)");
  EXPECT_EQ(Message("QQ=A"), "descriptors: not base64 (data after '=')");
  EXPECT_EQ(Message("Q==="), "descriptors: not base64 (misplaced '=')");
  EXPECT_EQ(Message("QR=="), "descriptors: not base64 (non-zero trailing bits)");
  EXPECT_EQ(Message("QQ="), "descriptors: not base64 (bad padding)");
  EXPECT_EQ(Message("QQ=="), "");
}

// On random strings over the alphabet, padding and whitespace, the decoder
// accepts exactly what libsodium accepts, with the same bytes.
TEST(Base64, AgreesWithLibsodiumOnRandomText) {
  ASSERT_GE(sodium_init(), 0);
  std::mt19937 rng(9);
  const std::string chars = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/= \n*";
  int accepted = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    std::string text(rng() % 13, ' ');
    for (auto& c : text) c = chars[rng() % (trial % 3 == 0 ? chars.size() : 64)];
    std::string reference;
    const bool ok = SodiumDecode(text, &reference);
    EXPECT_EQ(Message(text).empty(), ok) << "'" << text << "'";
    if (ok) {
      ++accepted;
      EXPECT_EQ(Base64Decode(text, "x"), reference) << "'" << text << "'";
    }
  }
  EXPECT_GT(accepted, 1000);
}

}  // namespace
}  // namespace linecloud
