// The secret lifting key of a map. Lifting is permanent: the same map must
// always be lifted with the same key, because two liftings of one point with
// different directions intersect in the point itself.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>

namespace linecloud {

class LiftingKey {
 public:
  static constexpr size_t kBytes = 32;
  using Bytes = std::array<uint8_t, kBytes>;
  using Id = std::array<uint8_t, 16>;

  explicit LiftingKey(const Bytes& bytes) : bytes_(bytes) {}

  // A fresh key from the operating system's randomness (libsodium's
  // randombytes, i.e. getrandom(2)).
  static LiftingKey Generate();

  const Bytes& bytes() const { return bytes_; }

  // A public fingerprint of the key (keyed BLAKE2b of a constant): lets a map
  // record which key lifted it without revealing anything about the key.
  Id Fingerprint() const;

  // A 32-byte subkey for one purpose (keyed BLAKE2b of `purpose`).
  Bytes DeriveSubkey(const std::string& purpose) const;

 private:
  Bytes bytes_;
};

std::string ToHex(const uint8_t* data, size_t size);
template <size_t N>
std::string ToHex(const std::array<uint8_t, N>& a) {
  return ToHex(a.data(), N);
}

// Parses exactly 2*size hex digits into `out`; false on any other input.
bool ParseHex(std::string_view hex, uint8_t* out, size_t size);

// Key files hold the key as 64 hex digits (comment lines start with '#').
// Reading throws Error naming the file if it is missing or malformed, and
// warns on stderr when group or others can read it.
LiftingKey ReadKeyFile(const std::string& path);
// Creates the file with permissions 0600; refuses to overwrite an existing one.
void WriteKeyFile(const std::string& path, const LiftingKey& key);

// Calls sodium_init() once; throws Error if libsodium cannot initialise.
void EnsureSodiumInitialized();

}  // namespace linecloud
