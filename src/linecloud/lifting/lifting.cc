#include "linecloud/lifting/lifting.h"

#include <sodium.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <numbers>
#include <numeric>

#include "linecloud/util/error.h"

namespace linecloud {
namespace {

constexpr char kDirectionPurpose[] = "linecloud/lift/direction/v1";
constexpr char kLineIdPurpose[] = "linecloud/lift/line-id/v1";
// ChaCha20's 8-byte nonce; the 64-bit block counter carries the point id.
constexpr unsigned char kNonce[crypto_stream_chacha20_NONCEBYTES] = {'l', 'c', 'd', 'i',
                                                                     'r', 'v', '0', '1'};
constexpr size_t kBlockBytes = 64;
constexpr size_t kMaxRun = 64;  // blocks generated per libsodium call

double Uniform53(const unsigned char* bytes) {
  uint64_t x;
  std::memcpy(&x, bytes, 8);
  return static_cast<double>(x >> 11) * 0x1.0p-53;  // [0, 1)
}

Eigen::Vector3d SphereFromUniforms(double u1, double u2) {
  const double z = 1.0 - 2.0 * u1;
  const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
  const double phi = 2.0 * std::numbers::pi * u2;
  return Eigen::Vector3d(r * std::cos(phi), r * std::sin(phi), z);
}

// Speck64/128 (Beaulieu, Shors, Smith, Treatman-Clark, Weeks, Wingers, "The
// SIMON and SPECK lightweight block ciphers", DAC 2015): a 64-bit block
// cipher, i.e. a keyed permutation of the 64-bit ids. 27 rounds of
//   x ← ((x ⋙ 8) + y) ⊕ k_i,   y ← (y ⋘ 3) ⊕ x
// on 32-bit words, round keys from the 128-bit key by the same round function.
constexpr int kSpeckRounds = 27;
using RoundKeys = std::array<uint32_t, kSpeckRounds>;

constexpr uint32_t Rotr(uint32_t v, int r) { return (v >> r) | (v << (32 - r)); }
constexpr uint32_t Rotl(uint32_t v, int r) { return (v << r) | (v >> (32 - r)); }

RoundKeys SpeckKeySchedule(const std::array<uint32_t, 4>& key) {
  RoundKeys k;
  std::array<uint32_t, kSpeckRounds + 2> l;
  k[0] = key[0];
  l[0] = key[1], l[1] = key[2], l[2] = key[3];
  for (int i = 0; i < kSpeckRounds - 1; ++i) {
    l[i + 3] = (k[i] + Rotr(l[i], 8)) ^ static_cast<uint32_t>(i);
    k[i + 1] = Rotl(k[i], 3) ^ l[i + 3];
  }
  return k;
}

// The block is (x, y) = (high word, low word) of the id.
uint64_t SpeckEncrypt(const RoundKeys& k, uint64_t block) {
  uint32_t x = static_cast<uint32_t>(block >> 32), y = static_cast<uint32_t>(block);
  for (int i = 0; i < kSpeckRounds; ++i) {
    x = (Rotr(x, 8) + y) ^ k[i];
    y = Rotl(y, 3) ^ x;
  }
  return (static_cast<uint64_t>(x) << 32) | y;
}

uint64_t SpeckDecrypt(const RoundKeys& k, uint64_t block) {
  uint32_t x = static_cast<uint32_t>(block >> 32), y = static_cast<uint32_t>(block);
  for (int i = kSpeckRounds - 1; i >= 0; --i) {
    y = Rotr(y ^ x, 3);
    x = Rotl((x ^ k[i]) - y, 8);
  }
  return (static_cast<uint64_t>(x) << 32) | y;
}

RoundKeys LineIdKey(const LiftingKey& key) {
  const LiftingKey::Bytes subkey = key.DeriveSubkey(kLineIdPurpose);
  std::array<uint32_t, 4> words;
  std::memcpy(words.data(), subkey.data(), sizeof(words));
  return SpeckKeySchedule(words);
}

}  // namespace

uint64_t LineIdOfPoint(const LiftingKey& key, uint64_t point_id) {
  return SpeckEncrypt(LineIdKey(key), point_id);
}

uint64_t PointIdOfLine(const LiftingKey& key, uint64_t line_id) {
  return SpeckDecrypt(LineIdKey(key), line_id);
}

std::vector<uint64_t> PointIdsOfLines(const LiftingKey& key, std::span<const uint64_t> line_ids) {
  const RoundKeys k = LineIdKey(key);
  std::vector<uint64_t> out(line_ids.size());
  for (size_t i = 0; i < line_ids.size(); ++i) out[i] = SpeckDecrypt(k, line_ids[i]);
  return out;
}

uint64_t Speck64Encrypt(const std::array<uint32_t, 4>& key, uint64_t block) {
  return SpeckEncrypt(SpeckKeySchedule(key), block);
}

std::vector<uint64_t> LineIdsOfPoints(const LiftingKey& key, std::span<const uint64_t> point_ids) {
  const RoundKeys k = LineIdKey(key);
  std::vector<uint64_t> out(point_ids.size());
  for (size_t i = 0; i < point_ids.size(); ++i) out[i] = SpeckEncrypt(k, point_ids[i]);
  return out;
}

void KeyedDirections(const LiftingKey& key, std::span<const uint64_t> ids,
                     Eigen::Vector3d* directions, uint8_t* compact_indices) {
  const LiftingKey::Bytes subkey = key.DeriveSubkey(kDirectionPurpose);
  static const std::array<unsigned char, kMaxRun* kBlockBytes> kZeros = {};
  std::array<unsigned char, kMaxRun * kBlockBytes> stream;
  size_t k = 0;
  while (k < ids.size()) {
    // Consecutive ids share one keystream call (counter increments per block).
    size_t run = 1;
    while (k + run < ids.size() && run < kMaxRun && ids[k + run] == ids[k] + run) {
      ++run;
    }
    crypto_stream_chacha20_xor_ic(stream.data(), kZeros.data(), run * kBlockBytes, kNonce, ids[k],
                                  subkey.data());
    for (size_t j = 0; j < run; ++j) {
      const unsigned char* block = stream.data() + j * kBlockBytes;
      directions[k + j] = SphereFromUniforms(Uniform53(block), Uniform53(block + 8));
      if (compact_indices) compact_indices[k + j] = block[16];
    }
    k += run;
  }
  sodium_memzero(stream.data(), stream.size());
}

LineCloud LiftPoints(std::span<const uint64_t> ids, std::span<const Eigen::Vector3d> points,
                     const LiftingKey& key, const LiftingOptions& options) {
  EnsureSodiumInitialized();
  std::vector<Eigen::Vector3d> directions(ids.size());
  std::vector<uint8_t> indices(ids.size());
  KeyedDirections(key, ids, directions.data(), indices.data());
  return LiftPoints(ids, points, key, options, directions, indices);
}

LineCloud LiftPoints(std::span<const uint64_t> ids, std::span<const Eigen::Vector3d> points,
                     const LiftingKey& key, const LiftingOptions& options,
                     std::span<const Eigen::Vector3d> directions,
                     std::span<const uint8_t> indices) {
  EnsureSodiumInitialized();
  if (ids.size() != points.size()) {
    Fail("lifting: {} ids but {} points", ids.size(), points.size());
  }
  for (size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) {
      Fail("lifting: point {} has non-finite coordinates", ids[i]);
    }
  }
  const bool compact_key = key.directions() == DirectionSet::kCompact256;
  if (options.encoding == LineEncoding::kCompact && !compact_key) {
    Fail(
        "lifting: this model's key draws its directions on the whole sphere, and the compact "
        "encoding's 256 directions would put a second line through every point. Lift it with "
        "the full encoding (no --compact); only a model whose key was created with --compact "
        "can be stored compactly");
  }
  if (directions.size() != ids.size() || (compact_key && indices.size() != ids.size())) {
    Fail("lifting: {} ids but {} directions and {} compact indices", ids.size(), directions.size(),
         indices.size());
  }
  for (size_t i = 0; i < directions.size() && !compact_key; ++i) {
    if (!(std::abs(directions[i].norm() - 1) <= 1e-9)) {
      Fail("lifting: the direction of point {} is not a unit vector", ids[i]);
    }
  }
  // Stored in increasing line-id order: a pseudo-random order of the points.
  // (line id, input index) pairs sort contiguously.
  std::vector<std::pair<uint64_t, size_t>> order(ids.size());
  {
    const RoundKeys k = LineIdKey(key);
    for (size_t i = 0; i < ids.size(); ++i) order[i] = {SpeckEncrypt(k, ids[i]), i};
  }
  std::sort(order.begin(), order.end());

  LineCloud cloud;
  cloud.encoding = options.encoding;
  cloud.key_fingerprint = key.Fingerprint();
  cloud.ids.resize(ids.size());
  cloud.lines.resize(ids.size());
  if (options.encoding == LineEncoding::kCompact) cloud.compact.resize(ids.size());
  for (size_t k = 0; k < ids.size(); ++k) {
    const size_t i = order[k].second;
    cloud.ids[k] = order[k].first;
    if (!compact_key) {
      cloud.lines[k] = PluckerLine(directions[i], points[i].cross(directions[i]));
      continue;
    }
    CompactLine c;
    c.direction_index = indices[i];
    Eigen::Vector3d e1, e2;
    CompactBasis(c.direction_index, &e1, &e2);
    // The line through X with direction d meets the plane d·x = 0 at
    // X − (d·X) d, whose coordinates in (e1, e2) are (e1·X, e2·X).
    c.position[0] = static_cast<float>(e1.dot(points[i]));
    c.position[1] = static_cast<float>(e2.dot(points[i]));
    cloud.lines[k] = DecodeCompactLine(c);
    if (options.encoding == LineEncoding::kCompact) cloud.compact[k] = c;
  }
  for (size_t k = 1; k < cloud.ids.size(); ++k) {
    if (cloud.ids[k] == cloud.ids[k - 1]) {
      Fail("lifting: point id {} appears twice", PointIdOfLine(key, cloud.ids[k]));
    }
  }
  cloud.Check("lifting");
  return cloud;
}

}  // namespace linecloud
