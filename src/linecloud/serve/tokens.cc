#include "linecloud/serve/tokens.h"

#include <sodium.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>
#include <mutex>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "linecloud/io/json_util.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {

bool TokenEntry::MayUse(const std::string& map_id) const {
  return std::find(maps.begin(), maps.end(), "*") != maps.end() ||
         std::find(maps.begin(), maps.end(), map_id) != maps.end();
}

struct TokenStore::Buckets {
  struct Bucket {
    double tokens = 0;
    std::chrono::steady_clock::time_point last;
  };
  std::mutex mutex;
  std::map<std::string, Bucket> by_id;
};

TokenStore::TokenStore() : buckets_(std::make_shared<Buckets>()) {}

std::string TokenSha256Hex(const std::string& token) {
  std::array<unsigned char, crypto_hash_sha256_BYTES> h;
  crypto_hash_sha256(h.data(), reinterpret_cast<const unsigned char*>(token.data()), token.size());
  std::string hex(2 * h.size() + 1, '\0');
  sodium_bin2hex(hex.data(), hex.size(), h.data(), h.size());
  hex.pop_back();
  return hex;
}

TokenStore TokenStore::Read(const std::string& path) {
  if (sodium_init() < 0) Fail("libsodium could not be initialised");
  nlohmann::json j;
  try {
    j = ParseJsonUniqueKeys(ReadFilePrefix(path, 1 << 20), path);  // "admin" twice: refused
  } catch (const nlohmann::json::exception& e) {
    Fail("{}: not JSON ({})", path, e.what());
  }
  if (!j.is_object() || !j.contains("tokens") || !j["tokens"].is_array() || j["tokens"].empty()) {
    Fail("{}: expected {{\"tokens\": [...]}} with at least one token", path);
  }
  TokenStore store;
  for (size_t i = 0; i < j["tokens"].size(); ++i) {
    const nlohmann::json& t = j["tokens"][i];
    const std::string where = fmt::format("{}: tokens[{}]", path, i);
    if (!t.is_object()) Fail("{}: expected an object", where);
    TokenEntry e;
    if (!t.contains("id") || !t["id"].is_string() || t["id"].get<std::string>().empty()) {
      Fail("{}.id: expected a non-empty string", where);
    }
    e.id = t["id"].get<std::string>();
    if (!t.contains("sha256") || !t["sha256"].is_string()) {
      Fail("{}.sha256: expected the hex SHA-256 of the token", where);
    }
    const std::string hex = t["sha256"].get<std::string>();
    size_t len = 0;
    if (hex.size() != 64 ||
        sodium_hex2bin(e.sha256.data(), e.sha256.size(), hex.data(), hex.size(), nullptr, &len,
                       nullptr) != 0 ||
        len != 32) {
      Fail("{}.sha256: expected 64 hex digits", where);
    }
    if (!t.contains("maps") || !t["maps"].is_array() || t["maps"].empty()) {
      Fail("{}.maps: expected a list of map ids or [\"*\"]", where);
    }
    for (const auto& m : t["maps"]) {
      if (!m.is_string()) Fail("{}.maps: expected strings", where);
      e.maps.push_back(m.get<std::string>());
    }
    if (t.contains("requests_per_minute")) {
      if (!t["requests_per_minute"].is_number() || !(t["requests_per_minute"].get<double>() > 0)) {
        Fail("{}.requests_per_minute: expected a positive number", where);
      }
      e.requests_per_minute = t["requests_per_minute"].get<double>();
    }
    if (t.contains("admin")) {
      if (!t["admin"].is_boolean()) Fail("{}.admin: expected true or false", where);
      e.admin = t["admin"].get<bool>();
    }
    for (const TokenEntry& other : store.entries_) {
      if (other.id == e.id) Fail("{}.id: '{}' appears twice", where, e.id);
    }
    store.entries_.push_back(std::move(e));
  }
  return store;
}

std::optional<TokenEntry> TokenStore::Authenticate(const std::string& authorization) const {
  // The scheme's name is case-insensitive (RFC 7235: "bearer" too).
  constexpr std::string_view kBearer = "Bearer ";
  if (authorization.size() <= kBearer.size() ||
      !std::equal(kBearer.begin(), kBearer.end(), authorization.begin(), [](char a, char b) {
        return std::tolower(static_cast<unsigned char>(a)) ==
               std::tolower(static_cast<unsigned char>(b));
      })) {
    return std::nullopt;
  }
  const std::string token = authorization.substr(kBearer.size());
  // RFC 6750's token68 characters only: cpp-httplib 0.11.4 percent-decodes
  // header values, so "TOKEN%00junk" arrived as the token, a NUL and junk.
  const auto token68 = [](unsigned char c) {
    return std::isalnum(c) != 0 || c == '-' || c == '.' || c == '_' || c == '~' || c == '+' ||
           c == '/' || c == '=';
  };
  if (!std::all_of(token.begin(), token.end(), token68)) return std::nullopt;
  std::array<unsigned char, crypto_hash_sha256_BYTES> h;
  crypto_hash_sha256(h.data(), reinterpret_cast<const unsigned char*>(token.data()), token.size());
  // Every entry is compared (no early exit on the first match's position).
  std::optional<TokenEntry> found;
  for (const TokenEntry& e : entries_) {
    if (sodium_memcmp(e.sha256.data(), h.data(), h.size()) == 0) found = e;
  }
  return found;
}

std::optional<double> TokenStore::Throttle(const std::string& id, double requests_per_minute,
                                           std::chrono::steady_clock::time_point now) const {
  const double rate = requests_per_minute / 60.0;     // per second
  const double capacity = std::max(1.0, rate * 5.0);  // five seconds' worth of burst
  std::lock_guard<std::mutex> lock(buckets_->mutex);
  auto [it, fresh] = buckets_->by_id.try_emplace(id);
  Buckets::Bucket& b = it->second;
  if (fresh) {
    b.tokens = capacity;
    b.last = now;
  }
  b.tokens =
      std::min(capacity, b.tokens + rate * std::chrono::duration<double>(now - b.last).count());
  b.last = now;
  if (b.tokens >= 1.0) {
    b.tokens -= 1.0;
    return std::nullopt;
  }
  return (1.0 - b.tokens) / rate;
}

}  // namespace linecloud
