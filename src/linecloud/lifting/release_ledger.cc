#include "linecloud/lifting/release_ledger.h"

#include <sodium.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

constexpr std::string_view kMagic = "linecloud-release-ledger 2\n";
constexpr std::string_view kMagicV1 = "linecloud-release-ledger 1\n";
constexpr size_t kLineBytesV1 = 6 * 8 + 1;
constexpr size_t kLineBytes = kLineBytesV1 + 8;
constexpr size_t kObservationBytes = 8 + 4;
constexpr size_t kImageBytes = 8 + 3 * 8;
constexpr size_t kChecksumBytes = 32;

template <typename T>
void Put(std::string* out, const T& value) {
  out->append(reinterpret_cast<const char*>(&value), sizeof(T));
}

template <typename T>
T Get(const std::string& in, size_t* pos) {
  T value;
  std::memcpy(&value, in.data() + *pos, sizeof(T));
  *pos += sizeof(T);
  return value;
}

std::array<unsigned char, kChecksumBytes> Checksum(const char* data, size_t size) {
  EnsureSodiumInitialized();
  std::array<unsigned char, kChecksumBytes> sum;
  crypto_generichash(sum.data(), sum.size(), reinterpret_cast<const unsigned char*>(data), size,
                     nullptr, 0);
  return sum;
}

}  // namespace

void ReleaseLedger::Index() {
  const size_t slots = std::bit_ceil(std::max<size_t>(2 * observations.size(), 16));
  index_hash_.assign(slots, 0);
  index_line_.assign(slots, 0);
  for (const auto& [hash, line] : observations) {
    size_t h = static_cast<size_t>(hash) & (slots - 1);
    while (index_line_[h] != 0) h = (h + 1) & (slots - 1);
    index_hash_[h] = hash;
    index_line_[h] = line + 1;
  }
  indexed_ = observations.size();
}

int64_t ReleaseLedger::LineOfObservation(uint64_t hash) const {
  if (indexed_ == observations.size() && !index_line_.empty()) {
    const size_t mask = index_line_.size() - 1;
    for (size_t h = static_cast<size_t>(hash) & mask; index_line_[h] != 0; h = (h + 1) & mask) {
      if (index_hash_[h] == hash) return static_cast<int64_t>(index_line_[h]) - 1;
    }
    return -1;
  }
  const auto it =
      std::lower_bound(observations.begin(), observations.end(), std::make_pair(hash, uint32_t{0}));
  return it != observations.end() && it->first == hash ? static_cast<int64_t>(it->second) : -1;
}

const Eigen::Vector3d* ReleaseLedger::ImageCentre(uint64_t hash) const {
  const auto it = std::lower_bound(images.begin(), images.end(), hash,
                                   [](const auto& e, uint64_t h) { return e.first < h; });
  return it != images.end() && it->first == hash ? &it->second : nullptr;
}

ObservationHasher::ObservationHasher(const LiftingKey& key) {
  const LiftingKey::Bytes subkey = key.DeriveSubkey("linecloud/ledger/observation/v1");
  static_assert(crypto_shorthash_KEYBYTES == 16);
  std::memcpy(key_, subkey.data(), sizeof(key_));
}

uint64_t ObservationHasher::Image(std::string_view name) const {
  uint64_t out;
  crypto_shorthash(reinterpret_cast<unsigned char*>(&out),
                   reinterpret_cast<const unsigned char*>(name.data()), name.size(), key_);
  return out;
}

uint64_t ObservationHasher::Observation(uint64_t image_hash, uint32_t point2D_idx) const {
  unsigned char in[12];
  std::memcpy(in, &image_hash, 8);
  std::memcpy(in + 8, &point2D_idx, 4);
  uint64_t out;
  crypto_shorthash(reinterpret_cast<unsigned char*>(&out), in, sizeof(in), key_);
  return out;
}

uint64_t ObservationHasher::ImageFeatures(std::string_view name, size_t count,
                                          std::span<const Eigen::Vector2d> first) const {
  constexpr size_t kFirst = 16;
  if (count < kFirst || first.size() < kFirst) return Image(name);
  std::vector<int64_t> words = {static_cast<int64_t>(count)};
  for (size_t k = 0; k < kFirst; ++k) {
    words.push_back(std::llround(std::clamp(first[k].x(), -1e9, 1e9)));
    words.push_back(std::llround(std::clamp(first[k].y(), -1e9, 1e9)));
  }
  return Image(std::string_view(reinterpret_cast<const char*>(words.data()), 8 * words.size()));
}

DescriptorSketcher::DescriptorSketcher(const LiftingKey& key, int dim) : dim_(dim) {
  if (dim <= 0 || dim > 4096) Fail("descriptor sketch: dimension {}", dim);
  const LiftingKey::Bytes subkey = key.DeriveSubkey("linecloud/ledger/descriptor-sketch/v1");
  std::vector<unsigned char> bits(static_cast<size_t>(dim) * 64 / 8 + 1);
  static_assert(crypto_stream_chacha20_KEYBYTES == 32);
  const unsigned char nonce[crypto_stream_chacha20_NONCEBYTES] = {0};
  crypto_stream_chacha20(bits.data(), bits.size(), nonce, subkey.data());
  signs_.resize(static_cast<size_t>(dim) * 64);
  for (size_t k = 0; k < signs_.size(); ++k) signs_[k] = (bits[k / 8] >> (k % 8)) & 1 ? 1 : -1;
}

uint64_t DescriptorSketcher::Sketch(std::span<const uint8_t> d) const {
  if (d.size() != static_cast<size_t>(dim_)) {
    Fail("descriptor sketch: {} values, expected {}", d.size(), dim_);
  }
  uint64_t out = 0;
  for (int b = 0; b < 64; ++b) {
    const int8_t* s = signs_.data() + static_cast<size_t>(b) * dim_;
    int64_t sum = 0;
    for (int k = 0; k < dim_; ++k) sum += s[k] * static_cast<int64_t>(d[k]);
    out |= static_cast<uint64_t>(sum > 0) << b;
  }
  return out == 0 ? 1 : out;
}

int SketchDistance(uint64_t a, uint64_t b) { return a == 0 || b == 0 ? 64 : std::popcount(a ^ b); }

std::string LedgerPath(const std::string& dir, const LiftingKey::Id& fingerprint) {
  return JoinPaths(dir, ToHex(fingerprint) + ".ledger");
}

ReleaseLedger ReadLedger(const std::string& path) {
  ReleaseLedger ledger;
  if (!FileExists(path)) return ledger;
  const size_t header_v1 = kMagic.size() + 3 * 8;
  const size_t header = header_v1 + 8;  // version 2: the released diagonal
  std::string data = ReadFilePrefix(path, header);
  const bool v1 = data.size() >= kMagicV1.size() && data.compare(0, kMagicV1.size(), kMagicV1) == 0;
  if (!v1 && (data.size() < kMagic.size() || data.compare(0, kMagic.size(), kMagic) != 0)) {
    Fail("{}: not a linecloud release ledger", path);
  }
  const size_t line_bytes = v1 ? kLineBytesV1 : kLineBytes;
  const size_t head = v1 ? header_v1 : header;
  if (data.size() < head) Fail("{}: truncated release ledger (header)", path);
  size_t pos = kMagic.size();
  const uint64_t n_lines = Get<uint64_t>(data, &pos);
  const uint64_t n_obs = Get<uint64_t>(data, &pos);
  const uint64_t n_images = Get<uint64_t>(data, &pos);
  const double diagonal = v1 ? 0.0 : Get<double>(data, &pos);
  if (!(diagonal >= 0) || !std::isfinite(diagonal)) {
    Fail("{}: corrupt release ledger (diagonal {})", path, diagonal);
  }
  constexpr uint64_t kMax = uint64_t{1} << 32;
  if (n_lines >= kMax || n_obs >= kMax || n_images >= kMax) {
    Fail("{}: corrupt release ledger (counts {} / {} / {})", path, n_lines, n_obs, n_images);
  }
  const uint64_t size = head + n_lines * line_bytes + n_obs * kObservationBytes +
                        n_images * kImageBytes + kChecksumBytes;
  std::error_code ec;
  const uint64_t on_disk = std::filesystem::file_size(path, ec);
  if (ec || on_disk != size) {
    Fail("{}: corrupt release ledger ({} bytes, its counts say {})", path, on_disk, size);
  }
  data = ReadFilePrefix(path, size + 1);
  if (data.size() != size) {
    Fail("{}: corrupt release ledger ({} bytes, its counts say {})", path, data.size(), size);
  }
  const auto sum = Checksum(data.data(), size - kChecksumBytes);
  if (std::memcmp(sum.data(), data.data() + size - kChecksumBytes, kChecksumBytes) != 0) {
    Fail("{}: corrupt release ledger (checksum); restore it from a backup", path);
  }
  ledger.diagonal = diagonal;
  ledger.lines.resize(n_lines);
  ledger.compact.resize(n_lines);
  ledger.sketch.assign(n_lines, 0);
  for (uint64_t i = 0; i < n_lines; ++i) {
    for (int k = 0; k < 3; ++k) ledger.lines[i].v[k] = Get<double>(data, &pos);
    for (int k = 0; k < 3; ++k) ledger.lines[i].w[k] = Get<double>(data, &pos);
    ledger.compact[i] = Get<uint8_t>(data, &pos);
    if (!v1) ledger.sketch[i] = Get<uint64_t>(data, &pos);
    if (!ledger.lines[i].IsValid(1e-6)) Fail("{}: corrupt release ledger (line {})", path, i);
  }
  ledger.observations.resize(n_obs);
  for (auto& [hash, line] : ledger.observations) {
    hash = Get<uint64_t>(data, &pos);
    line = Get<uint32_t>(data, &pos);
    if (line >= n_lines) Fail("{}: corrupt release ledger (observation of line {})", path, line);
  }
  ledger.images.resize(n_images);
  for (auto& [hash, centre] : ledger.images) {
    hash = Get<uint64_t>(data, &pos);
    for (int k = 0; k < 3; ++k) centre[k] = Get<double>(data, &pos);
  }
  const auto by_hash = [](const auto& a, const auto& b) { return a.first < b.first; };
  const auto same_hash = [](const auto& a, const auto& b) { return a.first == b.first; };
  if (!std::is_sorted(ledger.observations.begin(), ledger.observations.end(), by_hash) ||
      std::adjacent_find(ledger.observations.begin(), ledger.observations.end(), same_hash) !=
          ledger.observations.end() ||
      !std::is_sorted(ledger.images.begin(), ledger.images.end(), by_hash)) {
    Fail("{}: corrupt release ledger (unsorted)", path);
  }
  ledger.Index();
  return ledger;
}

void WriteLedger(const std::string& path, const ReleaseLedger& ledger) {
  if (ledger.compact.size() != ledger.lines.size() || ledger.sketch.size() != ledger.lines.size()) {
    Fail("{}: release ledger with {} lines but {} compact indices and {} sketches", path,
         ledger.lines.size(), ledger.compact.size(), ledger.sketch.size());
  }
  // Streamed through the checksum in blocks: no second copy of a large ledger.
  WriteFileAtomically(
      path,
      [&](std::ostream& os) {
        EnsureSodiumInitialized();
        crypto_generichash_state state;
        crypto_generichash_init(&state, nullptr, 0, kChecksumBytes);
        std::string block;
        const auto flush = [&](bool force) {
          if (!force && block.size() < (1u << 20)) return;
          crypto_generichash_update(&state, reinterpret_cast<const unsigned char*>(block.data()),
                                    block.size());
          os.write(block.data(), static_cast<std::streamsize>(block.size()));
          block.clear();
        };
        block.append(kMagic);
        Put<uint64_t>(&block, ledger.lines.size());
        Put<uint64_t>(&block, ledger.observations.size());
        Put<uint64_t>(&block, ledger.images.size());
        Put<double>(&block, ledger.diagonal);
        for (size_t i = 0; i < ledger.lines.size(); ++i) {
          for (int k = 0; k < 3; ++k) Put<double>(&block, ledger.lines[i].v[k]);
          for (int k = 0; k < 3; ++k) Put<double>(&block, ledger.lines[i].w[k]);
          Put<uint8_t>(&block, ledger.compact[i]);
          Put<uint64_t>(&block, ledger.sketch[i]);
          flush(false);
        }
        for (const auto& [hash, line] : ledger.observations) {
          Put<uint64_t>(&block, hash);
          Put<uint32_t>(&block, line);
          flush(false);
        }
        for (const auto& [hash, centre] : ledger.images) {
          Put<uint64_t>(&block, hash);
          for (int k = 0; k < 3; ++k) Put<double>(&block, centre[k]);
          flush(false);
        }
        flush(true);
        std::array<unsigned char, kChecksumBytes> sum;
        crypto_generichash_final(&state, sum.data(), sum.size());
        os.write(reinterpret_cast<const char*>(sum.data()), sum.size());
      },
      0600);
}

}  // namespace linecloud
