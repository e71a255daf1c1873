#include "linecloud/util/log.h"
#include "linecloud/lifting/key.h"

#include <fcntl.h>
#include <sodium.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string_view>

#include "linecloud/util/error.h"
#include "linecloud/util/file.h"
#include "linecloud/util/text_parser.h"

namespace linecloud {

void EnsureSodiumInitialized() {
  static const int rc = sodium_init();
  if (rc < 0) Fail("libsodium failed to initialise");
}

std::string_view DirectionSetName(DirectionSet set) {
  return set == DirectionSet::kCompact256 ? "compact256" : "sphere";
}

DirectionSet DirectionSetFromName(std::string_view name, std::string_view source) {
  if (name == "sphere") return DirectionSet::kSphere;
  if (name == "compact256") return DirectionSet::kCompact256;
  Fail("{}: unknown direction set '{}' (expected sphere or compact256)", source, name);
}

LiftingKey LiftingKey::Generate(DirectionSet directions) {
  EnsureSodiumInitialized();
  Bytes bytes;
  randombytes_buf(bytes.data(), bytes.size());
  return LiftingKey(bytes, directions);
}

LiftingKey::Id LiftingKey::Fingerprint() const {
  EnsureSodiumInitialized();
  // Sphere keys keep the fingerprint they had before direction sets existed.
  const std::string_view kContext = directions_ == DirectionSet::kSphere
                                        ? "linecloud/key-fingerprint/v1"
                                        : "linecloud/key-fingerprint/compact256/v1";
  Id id;
  crypto_generichash(id.data(), id.size(), reinterpret_cast<const unsigned char*>(kContext.data()),
                     kContext.size(), bytes_.data(), bytes_.size());
  return id;
}

LiftingKey::Bytes LiftingKey::DeriveSubkey(const std::string& purpose) const {
  EnsureSodiumInitialized();
  Bytes subkey;
  crypto_generichash(subkey.data(), subkey.size(),
                     reinterpret_cast<const unsigned char*>(purpose.data()), purpose.size(),
                     bytes_.data(), bytes_.size());
  return subkey;
}

LiftingKey DemoLiftingKey() {
  EnsureSodiumInitialized();
  static constexpr std::string_view kSeed = "linecloud/demo-key/public/never-for-real-maps/v1";
  LiftingKey::Bytes bytes;
  crypto_generichash(bytes.data(), bytes.size(),
                     reinterpret_cast<const unsigned char*>(kSeed.data()), kSeed.size(), nullptr,
                     0);
  return LiftingKey(bytes, DirectionSet::kCompact256);
}

std::string ToHex(const uint8_t* data, size_t size) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string hex(2 * size, '0');
  for (size_t i = 0; i < size; ++i) {
    hex[2 * i] = kDigits[data[i] >> 4];
    hex[2 * i + 1] = kDigits[data[i] & 15];
  }
  return hex;
}

bool ParseHex(std::string_view hex, uint8_t* out, size_t size) {
  if (hex.size() != 2 * size) return false;
  const auto digit = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  for (size_t i = 0; i < size; ++i) {
    const int hi = digit(hex[2 * i]);
    const int lo = digit(hex[2 * i + 1]);
    if (hi < 0 || lo < 0) return false;
    out[i] = static_cast<uint8_t>(hi * 16 + lo);
  }
  return true;
}

LiftingKey ReadKeyFile(const std::string& path, bool allow_shared) {
  struct stat st;
  if (::stat(path.c_str(), &st) == 0 && (st.st_mode & 077) != 0) {
    if (!allow_shared) {
      Fail(
          "{}: key file is readable by other users (mode {:o}); run chmod 600 on it, or "
          "pass --allow-shared-key",
          path, st.st_mode & 0777);
    }
    LogWarning("{} is readable by other users; run chmod 600 on it", path);
  }
  const std::string text = ReadFileToString(path);
  TextLines lines(text, path);
  std::string_view line;
  if (!lines.Next(&line)) {
    Fail("{}: key file is empty (expected 64 hex digits)", path);
  }
  auto tokens = SplitWhitespace(line);
  DirectionSet directions = DirectionSet::kSphere;
  if (tokens.size() == 2 && tokens[0] == "directions") {
    directions = DirectionSetFromName(tokens[1], path);
    if (!lines.Next(&line)) Fail("{}: key file has no key after its directions line", path);
    tokens = SplitWhitespace(line);
  }
  if (tokens.size() != 1 || tokens[0].size() != 2 * LiftingKey::kBytes) {
    Fail("{}: malformed key file (expected one line of 64 hex digits)", path);
  }
  LiftingKey::Bytes bytes;
  if (!ParseHex(tokens[0], bytes.data(), bytes.size())) {
    Fail("{}: malformed key file (expected 64 hex digits)", path);
  }
  if (lines.Next(&line)) {
    Fail("{}: malformed key file (unexpected content after the key)", path);
  }
  return LiftingKey(bytes, directions);
}

void WriteKeyFile(const std::string& path, const LiftingKey& key) {
  const std::string text =
      "# linecloud lifting key: keep it secret, and reuse it for every lifting "
      "of this model\n"
      "directions " +
      std::string(DirectionSetName(key.directions())) + "\n" + ToHex(key.bytes()) + "\n";
  if (!WriteNewFile(path, text, 0600, "key file")) {
    Fail("{}: key file already exists; pass it with --key-file to reuse it", path);
  }
}

}  // namespace linecloud
