#include "linecloud/util/base64.h"

#include <array>

#include <sodium.h>

#include "linecloud/util/error.h"

namespace linecloud {

std::string Base64Encode(std::span<const uint8_t> bytes) {
  std::string out(sodium_base64_ENCODED_LEN(bytes.size(), sodium_base64_VARIANT_ORIGINAL), '\0');
  sodium_bin2base64(out.data(), out.size(), bytes.data(), bytes.size(),
                    sodium_base64_VARIANT_ORIGINAL);
  out.pop_back();  // the terminating NUL
  return out;
}

namespace {

// 0-63 for the alphabet, kSkip for ignored whitespace, kPad for '=', kBad otherwise.
constexpr uint8_t kSkip = 64, kPad = 65, kBad = 66;

constexpr std::array<uint8_t, 256> DecodeTable() {
  std::array<uint8_t, 256> t{};
  for (auto& v : t) v = kBad;
  constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  for (int i = 0; i < 64; ++i) t[static_cast<uint8_t>(kAlphabet[i])] = static_cast<uint8_t>(i);
  t[' '] = t['\n'] = t['\r'] = kSkip;
  t['='] = kPad;
  return t;
}

constexpr std::array<uint8_t, 256> kDecode = DecodeTable();

}  // namespace

// A table decoder: descriptors and photos are no secrets, and libsodium's
// constant-time decoder took 8 % of a client-features request (2.2 MB of
// base64 for 13 000 descriptors); `linecloud_bench --benchmark_filter=Base64`
// compares the two. The same strictness: padding to a multiple of 4, '=' only
// at the end, zero bits after the last byte.
std::string Base64Decode(std::string_view text, const std::string& field) {
  std::string out;
  out.reserve(text.size() / 4 * 3);
  uint32_t group = 0;
  int count = 0, pad = 0;
  for (const char ch : text) {
    const uint8_t v = kDecode[static_cast<uint8_t>(ch)];
    if (v < 64) {
      if (pad) Fail("{}: not base64 (data after '=')", field);
      group = group << 6 | v;
      if (++count == 4) {
        out.push_back(static_cast<char>(group >> 16));
        out.push_back(static_cast<char>(group >> 8 & 0xff));
        out.push_back(static_cast<char>(group & 0xff));
        group = 0;
        count = 0;
      }
    } else if (v == kPad) {
      if (count + pad < 2 || ++pad > 2) Fail("{}: not base64 (misplaced '=')", field);
    } else if (v == kBad) {
      Fail("{}: not base64", field);
    }
  }
  if (pad) {
    if (count + pad != 4) Fail("{}: not base64 (bad padding)", field);
    if (count == 2) {
      if (group & 0xf) Fail("{}: not base64 (non-zero trailing bits)", field);
      out.push_back(static_cast<char>(group >> 4));
    } else {
      if (group & 0x3) Fail("{}: not base64 (non-zero trailing bits)", field);
      out.push_back(static_cast<char>(group >> 10));
      out.push_back(static_cast<char>(group >> 2 & 0xff));
    }
  } else if (count != 0) {
    Fail("{}: not base64 (length not a multiple of 4)", field);
  }
  return out;
}

}  // namespace linecloud
