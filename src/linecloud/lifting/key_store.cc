#include "linecloud/lifting/key_store.h"

#include <sodium.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>

#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

constexpr char kSketchMagic[] = "linecloud-model-sketch 1";
constexpr size_t kMaxSketchElements = size_t{1} << 16;  // bottom-k sketch
constexpr size_t kMinShared = 3;
constexpr double kMinSharedFraction = 0.05;

struct Sketch {
  std::string key_path;
  uint64_t max_element = std::numeric_limits<uint64_t>::max();  // bottom-k cut
  std::vector<uint64_t> elements;                               // sorted, unique
};

std::vector<uint64_t> SortedUnique(std::span<const uint64_t> elements) {
  std::vector<uint64_t> v(elements.begin(), elements.end());
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}

std::string SketchText(const Sketch& s) {
  std::string out = fmt::format("{}\nkey {}\nelements {} {}\n", kSketchMagic, s.key_path,
                                s.elements.size(), s.max_element);
  const size_t start = out.size();
  out.resize(start + 8 * s.elements.size());
  std::memcpy(out.data() + start, s.elements.data(), 8 * s.elements.size());
  return out;
}

// Next '\n'-terminated line of `text` from *pos; Fail naming `path` if none.
std::string_view NextLine(std::string_view text, size_t* pos, const std::string& path) {
  const size_t end = text.find('\n', *pos);
  if (end == std::string_view::npos) Fail("{}: truncated model sketch", path);
  const std::string_view line = text.substr(*pos, end - *pos);
  *pos = end + 1;
  return line;
}

Sketch ReadSketch(const std::string& path) {
  const std::string text = ReadFileToString(path);
  size_t pos = 0;
  if (NextLine(text, &pos, path) != kSketchMagic) Fail("{}: not a linecloud model sketch", path);
  const std::string_view key_line = NextLine(text, &pos, path);
  if (key_line.substr(0, 4) != "key " || key_line.size() == 4) {
    Fail("{}: model sketch has no key path", path);
  }
  Sketch s;
  s.key_path = std::string(key_line.substr(4));
  const std::string count_line(NextLine(text, &pos, path));
  unsigned long long count = 0, max_element = 0;
  char extra = 0;
  if (std::sscanf(count_line.c_str(), "elements %llu %llu%c", &count, &max_element, &extra) != 2 ||
      count > kMaxSketchElements || text.size() - pos != 8 * count) {
    Fail("{}: corrupt model sketch (element count)", path);
  }
  s.max_element = max_element;
  s.elements.resize(count);
  std::memcpy(s.elements.data(), text.data() + pos, 8 * count);
  if (!std::is_sorted(s.elements.begin(), s.elements.end())) {
    Fail("{}: corrupt model sketch (unsorted elements)", path);
  }
  return s;
}

std::string AbsolutePath(const std::string& path) {
  std::error_code ec;
  const auto abs = std::filesystem::absolute(path, ec);
  return ec ? path : abs.lexically_normal().string();
}

}  // namespace

uint64_t SketchElement(uint64_t point_id, std::string_view image_name) {
  EnsureSodiumInitialized();
  static constexpr std::string_view kContext = "linecloud/model-sketch/v1";
  crypto_generichash_state state;
  crypto_generichash_init(&state, reinterpret_cast<const unsigned char*>(kContext.data()),
                          kContext.size(), 8);
  unsigned char id_bytes[8];
  std::memcpy(id_bytes, &point_id, 8);
  crypto_generichash_update(&state, id_bytes, 8);
  crypto_generichash_update(&state, reinterpret_cast<const unsigned char*>(image_name.data()),
                            image_name.size());
  uint64_t out;
  crypto_generichash_final(&state, reinterpret_cast<unsigned char*>(&out), 8);
  return out;
}

std::string KeyStore::DefaultDirectory() {
  if (const char* d = std::getenv("LINECLOUD_KEY_STORE"); d && *d) return d;
  if (const char* d = std::getenv("XDG_DATA_HOME"); d && *d) {
    return JoinPaths(JoinPaths(d, "linecloud"), "keys");
  }
  const char* home = std::getenv("HOME");
  if (!home || !*home) {
    Fail("no key store: set LINECLOUD_KEY_STORE (or HOME), or pass --key-file");
  }
  return JoinPaths(home, ".local/share/linecloud/keys");
}

KeyStore::KeyStore(std::string dir) : dir_(std::move(dir)) {
  if (!IsDirectory(dir_)) {
    CreateDirectories(dir_);
    if (::chmod(dir_.c_str(), 0700) != 0) {
      Fail("{}: cannot make the key store owner-only ({})", dir_, std::strerror(errno));
    }
  }
  struct stat st;
  if (::stat(dir_.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
    Fail("{}: key store is not a directory", dir_);
  }
  if ((st.st_mode & 077) != 0) {
    Fail("{}: key store is accessible by other users (mode {:o}); run chmod 700 on it", dir_,
         st.st_mode & 0777);
  }
}

std::optional<KeyStoreMatch> KeyStore::Find(std::span<const uint64_t> elements,
                                            bool allow_shared_key) const {
  const std::vector<uint64_t> mine = SortedUnique(elements);
  std::optional<Sketch> best;
  KeyStoreMatch match{.key_path = {}, .key = LiftingKey(LiftingKey::Bytes{})};
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(dir_, ec)) {
    if (entry.path().extension() != ".model") continue;
    Sketch s = ReadSketch(entry.path().string());
    const size_t comparable = static_cast<size_t>(
        std::upper_bound(mine.begin(), mine.end(), s.max_element) - mine.begin());
    size_t shared = 0;
    for (size_t i = 0; i < comparable; ++i) {
      shared += std::binary_search(s.elements.begin(), s.elements.end(), mine[i]);
    }
    const double needed = kMinSharedFraction * std::min(comparable, s.elements.size());
    if (shared < kMinShared || shared < needed) continue;
    if (best && shared <= match.shared) continue;
    match.shared = shared;
    match.comparable = comparable;
    best = std::move(s);
  }
  if (ec) Fail("{}: cannot list the key store ({})", dir_, ec.message());
  if (!best) return std::nullopt;
  if (!FileExists(best->key_path)) {
    Fail(
        "this model was lifted before with the key {}, which no longer exists; restore it (or "
        "pass it with --key-file). A new key would reveal the model's points",
        best->key_path);
  }
  match.key_path = best->key_path;
  match.key = ReadKeyFile(best->key_path, allow_shared_key);
  return match;
}

void KeyStore::Register(const LiftingKey& key, const std::string& key_path,
                        std::span<const uint64_t> elements) const {
  Sketch s;
  s.key_path = AbsolutePath(key_path);
  if (s.key_path.find('\n') != std::string::npos) Fail("{}: key path has a newline", key_path);
  s.elements = SortedUnique(elements);
  if (s.elements.size() > kMaxSketchElements) {
    s.elements.resize(kMaxSketchElements);
    s.max_element = s.elements.back();
  }
  // One sketch per key: a later registration (a model grown since) adds to it.
  const std::string path = JoinPaths(dir_, ToHex(key.Fingerprint()) + ".model");
  if (FileExists(path)) {
    const Sketch old = ReadSketch(path);
    std::vector<uint64_t> merged;
    std::set_union(old.elements.begin(), old.elements.end(), s.elements.begin(), s.elements.end(),
                   std::back_inserter(merged));
    s.max_element = std::min(old.max_element, s.max_element);
    merged.erase(std::upper_bound(merged.begin(), merged.end(), s.max_element), merged.end());
    if (merged.size() > kMaxSketchElements) {
      merged.resize(kMaxSketchElements);
      s.max_element = merged.back();
    }
    s.elements = std::move(merged);
  }
  const std::string text = SketchText(s);
  WriteFileAtomically(
      path, [&](std::ostream& os) { os << text; }, 0600);
}

KeyStoreMatch KeyStore::CreateKey(DirectionSet directions,
                                  std::span<const uint64_t> elements) const {
  const LiftingKey key = LiftingKey::Generate(directions);
  const std::string key_path = JoinPaths(dir_, ToHex(key.Fingerprint()) + ".key");
  WriteKeyFile(key_path, key);
  Register(key, key_path, elements);
  return {.key_path = key_path, .key = key, .shared = 0, .comparable = 0};
}

}  // namespace linecloud
