// The secret lifting key of a model. Lifting is permanent: the same model must
// always be lifted with the same key, because two liftings of one point with
// different directions intersect in the point itself. A key also fixes the
// set its directions are drawn from, so that every encoding of a point under
// one key is the same line (one point, one line).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>

namespace linecloud {

// Where a key's line directions come from.
enum class DirectionSet : uint8_t {
  // Uniform on the unit sphere: only the full (float64) encoding can store it.
  kSphere = 0,
  // One of the compact encoding's 256 fixed directions, with the line's
  // position rounded to float32 as the compact encoding stores it: the full
  // and the compact encodings then hold bit-identical lines.
  kCompact256 = 1,
};

std::string_view DirectionSetName(DirectionSet set);
// "sphere" or "compact256"; throws Error naming `source` otherwise.
DirectionSet DirectionSetFromName(std::string_view name, std::string_view source);

class LiftingKey {
 public:
  static constexpr size_t kBytes = 32;
  using Bytes = std::array<uint8_t, kBytes>;
  using Id = std::array<uint8_t, 16>;

  explicit LiftingKey(const Bytes& bytes, DirectionSet directions = DirectionSet::kSphere)
      : bytes_(bytes), directions_(directions) {}

  // A fresh key from the operating system's randomness (libsodium's
  // randombytes, i.e. getrandom(2)).
  static LiftingKey Generate(DirectionSet directions = DirectionSet::kSphere);

  const Bytes& bytes() const { return bytes_; }
  DirectionSet directions() const { return directions_; }

  // A public fingerprint of the key and its direction set (keyed BLAKE2b of a
  // constant): lets a map record which key lifted it without revealing
  // anything about the key. Keys that differ only in their direction set have
  // different fingerprints.
  Id Fingerprint() const;

  // A 32-byte subkey for one purpose (keyed BLAKE2b of `purpose`).
  Bytes DeriveSubkey(const std::string& purpose) const;

 private:
  Bytes bytes_;
  DirectionSet directions_;
};

std::string ToHex(const uint8_t* data, size_t size);
template <size_t N>
std::string ToHex(const std::array<uint8_t, N>& a) {
  return ToHex(a.data(), N);
}

// Parses exactly 2*size hex digits into `out`; false on any other input.
bool ParseHex(std::string_view hex, uint8_t* out, size_t size);

// A fixed, public key (compact256 directions) for the built-in demo and for
// tests: every run gives the same lines. Never for a real map — anyone can
// compute it.
LiftingKey DemoLiftingKey();

// Key files hold an optional line `directions sphere|compact256` and the key
// as 64 hex digits (comment lines start with '#'; a file without the
// directions line is a sphere key, as all keys were before direction sets).
// Reading throws Error naming the file if it is missing or malformed, and if
// group or others can read it, unless `allow_shared` (then it warns).
LiftingKey ReadKeyFile(const std::string& path, bool allow_shared = false);
// Creates the file with permissions 0600; refuses to overwrite an existing one.
void WriteKeyFile(const std::string& path, const LiftingKey& key);

// Calls sodium_init() once; throws Error if libsodium cannot initialise.
void EnsureSodiumInitialized();

}  // namespace linecloud
