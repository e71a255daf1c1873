// Who may call `linecloud serve`: TOKENS.json (docs/http_api.md) holds, per
// client, an id, the SHA-256 of its bearer token (never the token), the maps
// it may use ("*": all), its rate and whether it is an admin (metrics, the
// console's owner views). A presented token is hashed and compared with every
// entry in constant time (sodium_memcmp); each entry has a token bucket.
#pragma once

#include <chrono>
#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace linecloud {

struct TokenEntry {
  std::string id;
  std::array<unsigned char, 32> sha256{};
  std::vector<std::string> maps;  // "*" for every map
  double requests_per_minute = 600;
  bool admin = false;

  bool MayUse(const std::string& map_id) const;
};

// Hex SHA-256 of a token, as TOKENS.json stores it.
std::string TokenSha256Hex(const std::string& token);

class TokenStore {
 public:
  // No file: every request is allowed (loopback use).
  TokenStore();
  // Throws Error naming the file and the field on anything malformed.
  static TokenStore Read(const std::string& path);

  bool open() const { return entries_.empty(); }
  size_t size() const { return entries_.size(); }

  // The entry of "Bearer TOKEN" (the Authorization header), or nullopt.
  std::optional<TokenEntry> Authenticate(const std::string& authorization) const;

  // Takes one request from `id`'s bucket; when empty, the seconds until one is
  // back (Retry-After).
  std::optional<double> Throttle(
      const std::string& id, double requests_per_minute,
      std::chrono::steady_clock::time_point now = std::chrono::steady_clock::now()) const;
  // A reloaded file (SIGHUP) keeps the rates spent under the previous one.
  void KeepRatesOf(const TokenStore& previous) { buckets_ = previous.buckets_; }

 private:
  struct Buckets;
  std::vector<TokenEntry> entries_;
  std::shared_ptr<Buckets> buckets_;  // per token id, behind a mutex
};

}  // namespace linecloud
