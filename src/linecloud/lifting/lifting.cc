#include "linecloud/lifting/lifting.h"

#include <sodium.h>

#include <array>
#include <cmath>
#include <cstring>
#include <numbers>

#include "linecloud/util/error.h"

namespace linecloud {
namespace {

constexpr char kDirectionPurpose[] = "linecloud/lift/direction/v1";
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

}  // namespace

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
  LineCloud cloud;
  cloud.encoding = options.encoding;
  cloud.key_fingerprint = key.Fingerprint();
  cloud.ids.assign(ids.begin(), ids.end());
  cloud.lines.resize(ids.size());
  std::vector<Eigen::Vector3d> directions(ids.size());
  std::vector<uint8_t> indices;
  const bool compact = options.encoding == LineEncoding::kCompact;
  if (compact) indices.resize(ids.size());
  KeyedDirections(key, ids, directions.data(), compact ? indices.data() : nullptr);
  if (!compact) {
    for (size_t i = 0; i < ids.size(); ++i) {
      cloud.lines[i] = PluckerLine(directions[i], points[i].cross(directions[i]));
    }
  } else {
    cloud.compact.resize(ids.size());
    for (size_t i = 0; i < ids.size(); ++i) {
      CompactLine& c = cloud.compact[i];
      c.direction_index = indices[i];
      Eigen::Vector3d e1, e2;
      CompactBasis(c.direction_index, &e1, &e2);
      // The line through X with direction d meets the plane d·x = 0 at
      // X − (d·X) d, whose coordinates in (e1, e2) are (e1·X, e2·X).
      c.position[0] = static_cast<float>(e1.dot(points[i]));
      c.position[1] = static_cast<float>(e2.dot(points[i]));
      cloud.lines[i] = DecodeCompactLine(c);
    }
  }
  cloud.Check("lifting");
  return cloud;
}

}  // namespace linecloud
