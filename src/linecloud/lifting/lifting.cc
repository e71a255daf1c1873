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
constexpr int kFeistelRounds = 8;
// ChaCha20's 8-byte nonce; the 64-bit block counter carries the point id.
constexpr unsigned char kNonce[crypto_stream_chacha20_NONCEBYTES] = {
    'l', 'c', 'd', 'i', 'r', 'v', '0', '1'};
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

// The Feistel network's round keys: the first 16 bytes of a purpose subkey.
using ShortKey = std::array<unsigned char, crypto_shorthash_KEYBYTES>;

ShortKey LineIdKey(const LiftingKey& key) {
  const LiftingKey::Bytes subkey = key.DeriveSubkey(kLineIdPurpose);
  ShortKey k;
  std::memcpy(k.data(), subkey.data(), k.size());
  return k;
}

uint32_t FeistelRound(const ShortKey& k, int round, uint32_t half) {
  unsigned char in[5] = {static_cast<unsigned char>(round), static_cast<unsigned char>(half),
                         static_cast<unsigned char>(half >> 8),
                         static_cast<unsigned char>(half >> 16),
                         static_cast<unsigned char>(half >> 24)};
  unsigned char out[crypto_shorthash_BYTES];
  crypto_shorthash(out, in, sizeof(in), k.data());
  uint32_t f;
  std::memcpy(&f, out, 4);
  return f;
}

// A keyed permutation of the 64-bit ids (Luby–Rackoff: a balanced Feistel
// network with pseudo-random round functions is a pseudo-random permutation).
uint64_t FeistelForward(const ShortKey& k, uint64_t x) {
  uint32_t left = static_cast<uint32_t>(x >> 32), right = static_cast<uint32_t>(x);
  for (int r = 0; r < kFeistelRounds; ++r) {
    const uint32_t next = left ^ FeistelRound(k, r, right);
    left = right;
    right = next;
  }
  return (static_cast<uint64_t>(left) << 32) | right;
}

uint64_t FeistelInverse(const ShortKey& k, uint64_t y) {
  uint32_t left = static_cast<uint32_t>(y >> 32), right = static_cast<uint32_t>(y);
  for (int r = kFeistelRounds - 1; r >= 0; --r) {
    const uint32_t previous = right ^ FeistelRound(k, r, left);
    right = left;
    left = previous;
  }
  return (static_cast<uint64_t>(left) << 32) | right;
}

}  // namespace

uint64_t LineIdOfPoint(const LiftingKey& key, uint64_t point_id) {
  EnsureSodiumInitialized();
  return FeistelForward(LineIdKey(key), point_id);
}

uint64_t PointIdOfLine(const LiftingKey& key, uint64_t line_id) {
  EnsureSodiumInitialized();
  return FeistelInverse(LineIdKey(key), line_id);
}

std::vector<uint64_t> LineIdsOfPoints(const LiftingKey& key,
                                      std::span<const uint64_t> point_ids) {
  EnsureSodiumInitialized();
  const ShortKey k = LineIdKey(key);
  std::vector<uint64_t> out(point_ids.size());
  for (size_t i = 0; i < point_ids.size(); ++i) out[i] = FeistelForward(k, point_ids[i]);
  return out;
}

void KeyedDirections(const LiftingKey& key, std::span<const uint64_t> ids,
                     Eigen::Vector3d* directions, uint8_t* compact_indices) {
  const LiftingKey::Bytes subkey = key.DeriveSubkey(kDirectionPurpose);
  static const std::array<unsigned char, kMaxRun * kBlockBytes> kZeros = {};
  std::array<unsigned char, kMaxRun * kBlockBytes> stream;
  size_t k = 0;
  while (k < ids.size()) {
    // Consecutive ids share one keystream call (counter increments per block).
    size_t run = 1;
    while (k + run < ids.size() && run < kMaxRun &&
           ids[k + run] == ids[k] + run) {
      ++run;
    }
    crypto_stream_chacha20_xor_ic(stream.data(), kZeros.data(),
                                  run * kBlockBytes, kNonce, ids[k],
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

LineCloud LiftPoints(std::span<const uint64_t> ids,
                     std::span<const Eigen::Vector3d> points,
                     const LiftingKey& key, const LiftingOptions& options) {
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
    Fail("lifting: this model's key draws its directions on the whole sphere, and the compact "
         "encoding's 256 directions would put a second line through every point. Lift it with "
         "the full encoding (no --compact); only a model whose key was created with --compact "
         "can be stored compactly");
  }
  std::vector<Eigen::Vector3d> directions(ids.size());
  std::vector<uint8_t> indices(compact_key ? ids.size() : 0);
  KeyedDirections(key, ids, directions.data(), compact_key ? indices.data() : nullptr);
  const std::vector<uint64_t> line_ids = LineIdsOfPoints(key, ids);
  // Stored in increasing line-id order: a pseudo-random order of the points.
  std::vector<size_t> order(ids.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::sort(order.begin(), order.end(),
            [&](size_t a, size_t b) { return line_ids[a] < line_ids[b]; });

  LineCloud cloud;
  cloud.encoding = options.encoding;
  cloud.key_fingerprint = key.Fingerprint();
  cloud.ids.resize(ids.size());
  cloud.lines.resize(ids.size());
  if (options.encoding == LineEncoding::kCompact) cloud.compact.resize(ids.size());
  for (size_t k = 0; k < ids.size(); ++k) {
    const size_t i = order[k];
    cloud.ids[k] = line_ids[i];
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
