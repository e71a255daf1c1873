#include "linecloud/util/log.h"
#include "linecloud/lifting/key_store.h"

#include <fcntl.h>
#include <sodium.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <thread>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>

#include "linecloud/lifting/release_ledger.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

// Version 1: written before release ledgers; version 2: the key's releases
// are recorded in its ledger (identity.h), which must then exist.
constexpr char kSketchMagicV1[] = "linecloud-model-sketch 1";
constexpr char kSketchMagic[] = "linecloud-model-sketch 2";
constexpr size_t kMaxSketchElements = size_t{1} << 16;  // bottom-k sketch
constexpr size_t kMinShared = 3;
constexpr double kMinSharedFraction = 0.05;

struct Sketch {
  bool with_ledger = true;  // version 2
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

Sketch ParseSketch(const std::string& text, const std::string& path) {
  size_t pos = 0;
  const std::string_view magic = NextLine(text, &pos, path);
  if (magic != kSketchMagic && magic != kSketchMagicV1) {
    Fail("{}: not a linecloud model sketch", path);
  }
  const bool with_ledger = magic == kSketchMagic;
  const std::string_view key_line = NextLine(text, &pos, path);
  if (key_line.substr(0, 4) != "key " || key_line.size() == 4) {
    Fail("{}: model sketch has no key path", path);
  }
  Sketch s;
  s.with_ledger = with_ledger;
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

Sketch ReadSketch(const std::string& path) { return ParseSketch(ReadFileToString(path), path); }

// Writes `s` to `path`, merged with the sketch already there (one sketch per
// key: a model grown since, or an imported entry, adds to it).
void WriteMergedSketch(const std::string& path, Sketch s) {
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

// A key bundle: "linecloud-key-bundle 1\n", then per section a line
// "NAME SIZE\n" and SIZE bytes (key, model, ledger; the ledger may be empty),
// then a BLAKE2b-256 of everything before.
constexpr std::string_view kBundleMagic = "linecloud-key-bundle 1\n";
constexpr const char* kBundleSections[] = {"key", "model", "ledger"};

std::array<unsigned char, 32> BundleChecksum(std::string_view data) {
  EnsureSodiumInitialized();
  std::array<unsigned char, 32> sum;
  crypto_generichash(sum.data(), sum.size(), reinterpret_cast<const unsigned char*>(data.data()),
                     data.size(), nullptr, 0);
  return sum;
}

std::array<std::string, 3> ReadBundle(const std::string& path) {
  constexpr uint64_t kMaxBundle = uint64_t{1} << 36;  // 64 GiB
  std::error_code ec;
  const uint64_t size = std::filesystem::file_size(path, ec);
  if (ec) Fail("{}: cannot read the key bundle ({})", path, ec.message());
  const std::string head = ReadFilePrefix(path, kBundleMagic.size());
  if (head != kBundleMagic) Fail("{}: not a linecloud key bundle (linecloud keys export)", path);
  if (size > kMaxBundle) Fail("{}: {} bytes, more than any key bundle", path, size);
  const std::string data = ReadFileToString(path);
  if (data.size() < kBundleMagic.size() + 32) Fail("{}: truncated key bundle", path);
  const std::string_view body(data.data(), data.size() - 32);
  if (std::memcmp(BundleChecksum(body).data(), data.data() + body.size(), 32) != 0) {
    Fail("{}: damaged key bundle (checksum)", path);
  }
  std::array<std::string, 3> sections;
  size_t pos = kBundleMagic.size();
  for (int k = 0; k < 3; ++k) {
    const size_t end = body.find('\n', pos);
    if (end == std::string_view::npos) Fail("{}: damaged key bundle (section {})", path, k);
    const std::string line(body.substr(pos, end - pos));
    const std::string want = std::string(kBundleSections[k]) + " ";
    unsigned long long bytes = 0;
    char extra = 0;
    if (line.rfind(want, 0) != 0 ||
        std::sscanf(line.c_str() + want.size(), "%llu%c", &bytes, &extra) != 1 ||
        bytes > body.size() - end - 1) {
      Fail("{}: damaged key bundle (section '{}')", path, kBundleSections[k]);
    }
    sections[k] = std::string(body.substr(end + 1, bytes));
    pos = end + 1 + bytes;
  }
  if (pos != body.size()) Fail("{}: damaged key bundle (trailing bytes)", path);
  return sections;
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

uint64_t SketchObservationElement(uint32_t point2D_idx, const Eigen::Vector2d& xy) {
  EnsureSodiumInitialized();
  static constexpr std::string_view kContext = "linecloud/model-sketch/keypoint/v1";
  int64_t words[3] = {point2D_idx, std::llround(std::clamp(xy.x(), -1e9, 1e9)),
                      std::llround(std::clamp(xy.y(), -1e9, 1e9))};
  uint64_t out;
  crypto_generichash(reinterpret_cast<unsigned char*>(&out), 8,
                     reinterpret_cast<const unsigned char*>(words), sizeof(words),
                     reinterpret_cast<const unsigned char*>(kContext.data()), kContext.size());
  return out;
}

uint64_t SketchTrackElement(uint64_t point_id, uint32_t image_id, uint32_t point2D_idx) {
  EnsureSodiumInitialized();
  static constexpr std::string_view kContext = "linecloud/model-sketch/track/v1";
  unsigned char bytes[16];
  std::memcpy(bytes, &point_id, 8);
  std::memcpy(bytes + 8, &image_id, 4);
  std::memcpy(bytes + 12, &point2D_idx, 4);
  uint64_t out;
  crypto_generichash(reinterpret_cast<unsigned char*>(&out), 8, bytes, sizeof(bytes),
                     reinterpret_cast<const unsigned char*>(kContext.data()), kContext.size());
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

namespace {

// Creates `dir` and its missing parents, each with mode 0700 (whatever the
// umask): the folders above a key store reveal nothing, but others need not
// list them either.
void CreateOwnerOnlyDirectories(const std::string& dir) {
  std::filesystem::path built;
  for (const auto& part : std::filesystem::path(dir)) {
    built /= part;
    if (::mkdir(built.c_str(), 0700) == 0) {
      ::chmod(built.c_str(), 0700);
    } else if (errno != EEXIST) {
      Fail("{}: cannot create the key store ({}: {})", dir, built.string(), std::strerror(errno));
    }
  }
}

}  // namespace

KeyStore::KeyStore(std::string dir) : dir_(std::move(dir)) {
  struct stat st;
  if (::lstat(dir_.c_str(), &st) != 0) {
    CreateOwnerOnlyDirectories(dir_);
    if (::lstat(dir_.c_str(), &st) != 0) Fail("{}: cannot create the key store", dir_);
  }
  // A link could be re-pointed by whoever controls the folder it sits in.
  if (S_ISLNK(st.st_mode)) {
    Fail("{}: key store is a symbolic link; give the folder it names instead", dir_);
  }
  if (!S_ISDIR(st.st_mode)) Fail("{}: key store is not a directory", dir_);
  if (st.st_uid != ::geteuid()) {
    Fail("{}: key store belongs to another user (uid {}); use a store of your own", dir_,
         st.st_uid);
  }
  if ((st.st_mode & 077) != 0) {
    Fail("{}: key store is accessible by other users (mode {:o}); run chmod 700 on it", dir_,
         st.st_mode & 0777);
  }
  // No output of this process may land among the keys (util/file.h).
  ProtectDirectory(dir_);
}

KeyStore::Lock::Lock(const std::string& dir) {
  const std::string path = JoinPaths(dir, ".lock");
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0600);
  if (fd_ < 0) Fail("{}: cannot open the key store's lock ({})", path, std::strerror(errno));
  // Another process holding the lock is reported after a second and given
  // up on after LINECLOUD_LOCK_TIMEOUT seconds (default 60).
  double timeout = 60;
  if (const char* t = std::getenv("LINECLOUD_LOCK_TIMEOUT"); t && *t) {
    char* end = nullptr;
    const double v = std::strtod(t, &end);
    if (end != t && *end == '\0' && v >= 0 && v <= 86400) timeout = v;
  }
  const auto start = std::chrono::steady_clock::now();
  bool told = false;
  while (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    if (errno == EINTR) continue;
    if (errno != EWOULDBLOCK) {
      const std::string why = std::strerror(errno);
      ::close(fd_);
      Fail("{}: cannot lock the key store ({})", path, why);
    }
    const double waited =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (waited >= timeout) {
      ::close(fd_);
      Fail(
          "{}: the key store is locked by another process (a lift or localize still running?); "
          "gave up after {:g} s (LINECLOUD_LOCK_TIMEOUT)",
          path, timeout);
    }
    if (!told && waited >= 1.0) {
      LogWarning(
          "waiting for the key store's lock {}, held by another process (giving up after {:g} s)",
          path, timeout);
      told = true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

KeyStore::Lock::~Lock() {
  if (fd_ >= 0) ::close(fd_);  // closing releases the flock
}

std::optional<KeyStoreMatch> KeyStore::Find(std::span<const uint64_t> elements,
                                            bool allow_shared_key) const {
  // Not sorted (a model of a million points has ~12 million elements): each
  // entry's bottom-k cut selects the comparable ones, looked up in its sketch.
  const std::span<const uint64_t> mine = elements;
  struct Candidate {
    std::string entry;
    Sketch sketch;
    size_t shared = 0;
    size_t comparable = 0;
  };
  std::vector<Candidate> matches;
  std::vector<std::string> unreadable;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(dir_, ec)) {
    if (entry.path().extension() != ".model") continue;
    Candidate c;
    c.entry = entry.path().string();
    try {
      c.sketch = ReadSketch(c.entry);
    } catch (const Error& e) {
      // Never silently: the entry may be this model's, and its key would be
      // missed.
      unreadable.push_back(e.what());
      continue;
    }
    const std::vector<uint64_t>& theirs = c.sketch.elements;
    for (const uint64_t e : mine) {
      if (e > c.sketch.max_element) continue;
      ++c.comparable;
      c.shared += std::binary_search(theirs.begin(), theirs.end(), e);
    }
    const double needed = kMinSharedFraction * std::min(c.comparable, theirs.size());
    if (c.shared < kMinShared || c.shared < needed) continue;
    matches.push_back(std::move(c));
  }
  if (ec) Fail("{}: cannot list the key store ({})", dir_, ec.message());
  if (matches.empty() && !unreadable.empty()) {
    // The unreadable entry may be this model's: a new key would put a second
    // line through every point.
    Fail(
        "the key store has an unreadable entry, which may be this model's: {}. Restore it from "
        "a backup (or, if it is not this model's, move it out of {}); no key was created",
        unreadable.front(), dir_);
  }
  for (const std::string& why : unreadable) {
    LogWarning("key store entry skipped: {}", why);
  }
  if (matches.empty()) return std::nullopt;
  if (matches.size() > 1) {
    Fail(
        "this model matches two keys of the key store, {} (key {}) and {} (key {}): two "
        "liftings with different keys reveal the points they share. Keep the key whose maps were "
        "shared and retire the other entry (rename its .model file)",
        matches[0].entry, matches[0].sketch.key_path, matches[1].entry, matches[1].sketch.key_path);
  }
  const Candidate& best = matches.front();
  if (!FileExists(best.sketch.key_path)) {
    Fail(
        "this model was lifted before with the key {}, which no longer exists; restore it (or "
        "pass it with --key-file). A new key would reveal the model's points",
        best.sketch.key_path);
  }
  KeyStoreMatch match{.key_path = best.sketch.key_path,
                      .key = ReadKeyFile(best.sketch.key_path, allow_shared_key),
                      .shared = best.shared,
                      .comparable = best.comparable,
                      .with_ledger = best.sketch.with_ledger};
  // Entries are named by the fingerprint of the key they registered.
  const std::string registered = std::filesystem::path(best.entry).stem().string();
  if (ToHex(match.key.Fingerprint()) != registered) {
    Fail(
        "{}: this key now has the fingerprint {}, but this model was lifted with the key of "
        "fingerprint {} ({}): the key file was changed. Restore it; lifting with another key "
        "would reveal the model's points",
        match.key_path, ToHex(match.key.Fingerprint()), registered, best.entry);
  }
  return match;
}

std::array<uint8_t, 32> KeyStore::CacheSecret() const {
  const ProtectedWriteScope writing_the_store;
  const std::string path = JoinPaths(dir_, "cache.secret");
  const Lock lock = LockExclusive();
  if (!FileExists(path)) {
    std::array<uint8_t, 32> fresh;
    EnsureSodiumInitialized();
    randombytes_buf(fresh.data(), fresh.size());
    WriteNewFile(path, ToHex(fresh) + "\n", 0600, "the cache secret");
  }
  const std::string text = ReadFileToString(path);
  std::array<uint8_t, 32> secret;
  if (text.size() != 65 || text[64] != '\n' ||
      !ParseHex(std::string_view(text).substr(0, 64), secret.data(), secret.size())) {
    Fail("{}: corrupt cache secret (expected 64 hex digits); delete it to make a new one", path);
  }
  return secret;
}

void KeyStore::Retire(const LiftingKey::Id& fingerprint) const {
  const std::string path = JoinPaths(dir_, ToHex(fingerprint) + ".model");
  if (!FileExists(path)) return;
  if (std::rename(path.c_str(), (path + ".retired").c_str()) != 0) {
    Fail("{}: cannot retire the key store entry ({})", path, std::strerror(errno));
  }
}

void KeyStore::Register(const LiftingKey& key, const std::string& key_path,
                        std::span<const uint64_t> elements) const {
  const ProtectedWriteScope writing_the_store;
  Sketch s;
  s.key_path = AbsolutePath(key_path);
  if (s.key_path.find('\n') != std::string::npos) Fail("{}: key path has a newline", key_path);
  // The bottom-k: the smallest kMaxSketchElements distinct elements.
  std::vector<uint64_t> bottom(elements.begin(), elements.end());
  const bool cut = bottom.size() > 2 * kMaxSketchElements;
  if (cut) {
    std::nth_element(bottom.begin(), bottom.begin() + 2 * kMaxSketchElements, bottom.end());
    bottom.resize(2 * kMaxSketchElements);
  }
  s.elements = SortedUnique(bottom);
  if (cut && !s.elements.empty()) s.max_element = s.elements.back();
  if (s.elements.size() > kMaxSketchElements) {
    s.elements.resize(kMaxSketchElements);
    s.max_element = s.elements.back();
  }
  // One sketch per key: a later registration (a model grown since) adds to it.
  WriteMergedSketch(JoinPaths(dir_, ToHex(key.Fingerprint()) + ".model"), std::move(s));
}

void KeyStore::ExportEntry(const LiftingKey::Id& fingerprint, const std::string& bundle) const {
  const std::string model = JoinPaths(dir_, ToHex(fingerprint) + ".model");
  if (!FileExists(model)) Fail("{}: the key store has no entry {}", dir_, ToHex(fingerprint));
  const Sketch sketch = ReadSketch(model);
  const std::string ledger = JoinPaths(dir_, ToHex(fingerprint) + ".ledger");
  const std::array<std::string, 3> sections = {
      ReadFileToString(sketch.key_path), ReadFileToString(model),
      FileExists(ledger) ? ReadFileToString(ledger) : std::string()};
  std::string out(kBundleMagic);
  for (int k = 0; k < 3; ++k) {
    out += fmt::format("{} {}\n", kBundleSections[k], sections[k].size());
    out += sections[k];
  }
  const auto sum = BundleChecksum(out);
  out.append(reinterpret_cast<const char*>(sum.data()), sum.size());
  WriteFileAtomically(
      bundle, [&](std::ostream& os) { os << out; }, 0600);
}

std::string KeyStore::ImportEntry(const std::string& bundle, bool replace_ledger) const {
  const std::array<std::string, 3> sections = ReadBundle(bundle);
  const ProtectedWriteScope writing_the_store;
  // Every part is staged and checked by its own reader before anything is
  // installed: a refused bundle leaves the store as it was.
  std::vector<std::string> staged_files;
  struct Cleanup {
    std::vector<std::string>* files;
    ~Cleanup() {
      for (const std::string& f : *files) {
        std::error_code ec;
        std::filesystem::remove(f, ec);
      }
    }
  } cleanup{&staged_files};
  const auto staged = [&](const std::string& name, const std::string& bytes) {
    const std::string path = JoinPaths(dir_, ".import-" + name);
    WriteFileAtomically(
        path, [&](std::ostream& os) { os << bytes; }, 0600);
    staged_files.push_back(path);
    return path;
  };
  const std::string key_tmp = staged("key", sections[0]);
  const LiftingKey key = [&] {
    try {
      return ReadKeyFile(key_tmp);
    } catch (const Error& e) {
      Fail("{}: the bundle's key is damaged ({})", bundle, e.what());
    }
  }();
  const std::string fp = ToHex(key.Fingerprint());
  Sketch sketch = ParseSketch(sections[1], bundle + " (model registration)");
  const std::string key_path = JoinPaths(dir_, fp + ".key");
  const bool have_key = FileExists(key_path);
  if (have_key) {
    if (ReadKeyFile(key_path).Fingerprint() != key.Fingerprint()) {
      Fail("{}: holds another key under the bundle's fingerprint {}", key_path, fp);
    }
  } else {
    const std::optional<KeyStoreMatch> other = Find(sketch.elements);
    if (other && other->key.Fingerprint() != key.Fingerprint()) {
      Fail(
          "{}: this store already holds another key ({}) for the bundle's model: two keys of "
          "one place give its points back. Retire that key (or use another store) first",
          dir_, ToHex(other->key.Fingerprint()));
    }
  }
  const std::string ledger_path = JoinPaths(dir_, fp + ".ledger");
  std::string ledger_tmp;
  size_t ledger_lines = 0;
  if (!sections[2].empty()) {
    ledger_tmp = staged("ledger", sections[2]);
    try {
      ledger_lines = ReadLedger(ledger_tmp).lines.size();
    } catch (const Error& e) {
      Fail("{}: the bundle's release ledger is damaged ({})", bundle, e.what());
    }
    if (FileExists(ledger_path) && ReadFileToString(ledger_path) != sections[2] &&
        !replace_ledger) {
      Fail(
          "{}: this store's release ledger of key {} differs from the bundle's ({} vs {} "
          "lines): each store released maps the other does not know. Keep one store per "
          "place; --replace-ledger takes the bundle's",
          ledger_path, fp, ReadLedger(ledger_path).lines.size(), ledger_lines);
    }
  } else if (sketch.with_ledger && !FileExists(ledger_path)) {
    Fail("{}: the bundle's entry records releases but holds no ledger", bundle);
  }
  // Checked: installed ledger first (a key without its ledger is refused by lift), key, then
  // the registration that makes the key found.
  std::vector<std::string> did;
  if (!ledger_tmp.empty()) {
    std::filesystem::rename(ledger_tmp, ledger_path);
    did.push_back(fmt::format("ledger of {} released lines", ledger_lines));
  }
  if (have_key) {
    did.push_back("the key was already here");
  } else {
    std::filesystem::rename(key_tmp, key_path);
    did.push_back(fmt::format("key {}", key_path));
  }
  sketch.key_path = key_path;
  WriteMergedSketch(JoinPaths(dir_, fp + ".model"), std::move(sketch));
  did.push_back("the model's registration");
  std::string out;
  for (const std::string& d : did) out += (out.empty() ? "" : "; ") + d;
  return out;
}

}  // namespace linecloud
