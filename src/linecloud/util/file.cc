#include "linecloud/util/file.h"

#include <dirent.h>
#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <cerrno>
#include <mutex>
#include <vector>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "linecloud/util/error.h"

namespace linecloud {

void CheckReadableFile(const std::string& path) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) {
    FailFile(errno, "{}: cannot open for reading ({})", path, std::strerror(errno));
  }
  if (S_ISDIR(st.st_mode)) FailFile(EISDIR, "{}: is a directory, expected a file", path);
  // A FIFO without a writer would block forever in open(); devices and
  // sockets are no files to parse either.
  if (!S_ISREG(st.st_mode)) Fail("{}: is not a regular file (a device, FIFO or socket)", path);
}

std::string ReadFileToString(const std::string& path) {
  CheckReadableFile(path);
  std::ifstream file(path, std::ios::binary);
  if (!file) {
    FailFile(errno, "{}: cannot open for reading ({})", path, std::strerror(errno));
  }
  std::string data;
  file.seekg(0, std::ios::end);
  const std::streamoff size = file.tellg();
  if (size < 0) Fail("{}: cannot determine file size", path);
  data.resize(static_cast<size_t>(size));
  file.seekg(0, std::ios::beg);
  file.read(data.data(), size);
  if (!file) FailFile(EIO, "{}: read error", path);
  return data;
}

std::string ReadFilePrefix(const std::string& path, size_t max_bytes) {
  CheckReadableFile(path);
  std::ifstream file(path, std::ios::binary);
  if (!file) FailFile(errno, "{}: cannot open for reading ({})", path, std::strerror(errno));
  std::string data(max_bytes, '\0');
  file.read(data.data(), static_cast<std::streamsize>(max_bytes));
  data.resize(static_cast<size_t>(file.gcount()));
  return data;
}

bool FileExists(const std::string& path) {
  std::error_code ec;
  return std::filesystem::exists(path, ec);
}

bool IsDirectory(const std::string& path) {
  std::error_code ec;
  return std::filesystem::is_directory(path, ec);
}

namespace {

// Writes all of `data` to `fd`; false on error.
bool WriteAll(int fd, const std::string& data) {
  size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::write(fd, data.data() + done, data.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    done += static_cast<size_t>(n);
  }
  return true;
}

constexpr char kTemporaryPrefix[] = ".linecloud-";
constexpr size_t kTemporarySuffix = 6;  // mkstemp's XXXXXX
constexpr int kStaleTemporarySeconds = 60;

// Removes temporaries of our own naming in `dir` that a killed writer left:
// older than a minute and not locked (a live writer holds an exclusive flock
// on its temporary until the rename; the kernel drops it when a process dies).
void RemoveStaleTemporaries(const std::string& dir) {
  DIR* d = ::opendir(dir.c_str());
  if (d == nullptr) return;
  const time_t now = ::time(nullptr);
  const size_t prefix = sizeof(kTemporaryPrefix) - 1;
  while (const dirent* e = ::readdir(d)) {
    const std::string_view name(e->d_name);
    if (name.size() != prefix + kTemporarySuffix || name.substr(0, prefix) != kTemporaryPrefix) {
      continue;
    }
    const int fd = ::openat(::dirfd(d), e->d_name, O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) continue;
    struct stat st;
    if (::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_uid == ::geteuid() &&
        now - st.st_mtime > kStaleTemporarySeconds && ::flock(fd, LOCK_EX | LOCK_NB) == 0) {
      ::unlinkat(::dirfd(d), e->d_name, 0);
    }
    ::close(fd);
  }
  ::closedir(d);
}

// Opens a device or FIFO for writing without ever blocking on a FIFO that has
// no reader (open(2) would wait for one for ever), then writes blocking.
int OpenDeviceForWriting(const std::string& path, const std::string& shown) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0 && errno == ENXIO) {
    Fail("{}: is a FIFO that nothing reads: refusing to wait for a reader", shown);
  }
  if (fd < 0) FailFile(errno, "{}: cannot open for writing ({})", shown, std::strerror(errno));
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags >= 0) ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
  return fd;
}

}  // namespace

unsigned CurrentUmask() {
  // umask(2) can only be read by setting it, which races with other threads:
  // Linux reports it in /proc/self/status.
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("Umask:", 0) == 0) return std::stoul(line.substr(6), nullptr, 8) & 0777;
  }
  return 022;
}

namespace {

std::mutex protected_mutex;
std::vector<std::filesystem::path>& ProtectedDirectories() {
  static std::vector<std::filesystem::path> dirs;
  return dirs;
}
thread_local int protected_write_depth = 0;

std::filesystem::path Resolved(const std::string& path) {
  std::error_code ec;
  std::filesystem::path p = std::filesystem::absolute(path, ec);
  if (ec) return std::filesystem::path(path).lexically_normal();
  const std::filesystem::path c = std::filesystem::weakly_canonical(p, ec);
  return ec ? p.lexically_normal() : c;
}

}  // namespace

void ProtectDirectory(const std::string& dir) {
  const std::filesystem::path resolved = Resolved(dir);
  const std::lock_guard<std::mutex> lock(protected_mutex);
  auto& dirs = ProtectedDirectories();
  if (std::find(dirs.begin(), dirs.end(), resolved) == dirs.end()) dirs.push_back(resolved);
}

ProtectedWriteScope::ProtectedWriteScope() { ++protected_write_depth; }
ProtectedWriteScope::~ProtectedWriteScope() { --protected_write_depth; }

void CheckNotProtected(const std::string& path) {
  if (protected_write_depth > 0) return;
  const std::filesystem::path target = Resolved(path);
  const std::lock_guard<std::mutex> lock(protected_mutex);
  for (const auto& dir : ProtectedDirectories()) {
    const auto [d, t] = std::mismatch(dir.begin(), dir.end(), target.begin(), target.end());
    if (d == dir.end()) {
      Fail(
          "{}: is inside the key store {}{}: refusing to write there (a key or its release "
          "ledger would be lost); write it elsewhere",
          path, dir.string(),
          target.string() != std::filesystem::absolute(path).lexically_normal().string()
              ? fmt::format(" (through a link, as {})", target.string())
              : "");
    }
  }
}

void WriteFileAtomically(const std::string& path, const std::function<void(std::ostream&)>& write,
                         unsigned mode) {
  CheckNotProtected(path);
  // The content first: a failing writer touches no file at all.
  std::ostringstream buffer(std::ios::binary);
  write(buffer);
  if (!buffer) Fail("{}: cannot produce the output", path);
  const std::string data = std::move(buffer).str();  // moved out, not copied

  // Write through a link to the file it names (the link stays a link).
  std::string target = path;
  struct stat lst;
  if (::lstat(path.c_str(), &lst) == 0 && S_ISLNK(lst.st_mode)) {
    std::error_code ec;
    const std::filesystem::path resolved = std::filesystem::weakly_canonical(path, ec);
    if (ec) Fail("{}: cannot resolve the link ({})", path, ec.message());
    target = resolved.string();
  }
  struct stat st;
  if (::stat(target.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {
    if (S_ISDIR(st.st_mode)) FailFile(EISDIR, "{}: is a directory, expected a file", path);
    // A device or FIFO (/dev/null, /dev/stdout, a pipe): written through, never replaced.
    const int fd = OpenDeviceForWriting(target, path);
    const bool ok = WriteAll(fd, data);
    ::close(fd);
    if (!ok) FailFile(errno, "{}: write error ({})", path, std::strerror(errno));
    return;
  }
  // A regular file or none: an exclusive, unpredictable temporary file in the
  // same directory (mkstemp: O_CREAT | O_EXCL, so a planted file or link at
  // its name is never followed), synced, then renamed over the target.
  // The mode: a replaced file keeps its own (never more open than `mode`),
  // a new one gets `mode` less the umask, as open(2) would give it.
  const bool replacing = ::stat(target.c_str(), &st) == 0;
  const unsigned final_mode = replacing ? (st.st_mode & 0777 & mode) : (mode & ~CurrentUmask());
  const std::filesystem::path parent = std::filesystem::path(target).parent_path();
  const std::string dir = (parent.empty() ? std::filesystem::path(".") : parent).string();
  RemoveStaleTemporaries(dir);
  std::string tmp = dir + "/" + kTemporaryPrefix + "XXXXXX";
  const int fd = ::mkostemp(tmp.data(), O_CLOEXEC);
  if (fd < 0) {
    FailFile(errno, "{}: cannot create a file in its folder ({})", path, std::strerror(errno));
  }
  // Held until the rename: a temporary that nobody locks belongs to a dead writer.
  bool ok = ::flock(fd, LOCK_EX) == 0;
  ok = ok && ::fchmod(fd, final_mode) == 0;
  ok = ok && WriteAll(fd, data) && ::fsync(fd) == 0;
  const int error_number = errno;
  ::close(fd);
  if (!ok) {
    ::unlink(tmp.c_str());
    FailFile(error_number, "{}: write error ({})", path, std::strerror(error_number));
  }
  if (::rename(tmp.c_str(), target.c_str()) != 0) {
    const int error_number = errno;
    ::unlink(tmp.c_str());
    FailFile(error_number, "{}: cannot move into place ({})", path, std::strerror(error_number));
  }
}

bool WriteNewFile(const std::string& path, std::string_view text, unsigned mode,
                  std::string_view what) {
  CheckNotProtected(path);
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, mode);
  if (fd < 0 && errno == EEXIST) return false;
  if (fd < 0) FailFile(errno, "{}: cannot create {} ({})", path, what, std::strerror(errno));
  const bool ok = ::fchmod(fd, mode) == 0 && WriteAll(fd, std::string(text)) && ::fsync(fd) == 0;
  ::close(fd);
  if (!ok) {
    ::unlink(path.c_str());
    Fail("{}: cannot write {}", path, what);
  }
  return true;
}

void RefuseOutputOverInputs(const std::string& output, const std::vector<std::string>& inputs,
                            const std::string& option) {
  std::error_code ec;
  if (!std::filesystem::exists(output, ec)) return;
  for (const std::string& input : inputs) {
    if (input.empty()) continue;
    std::error_code e1;
    if (std::filesystem::equivalent(output, input, e1)) {
      Fail("{} {} is one of the command's inputs: refusing to overwrite it", option, output);
    }
    // An input folder (a COLMAP model): none of its files either.
    if (std::filesystem::is_directory(input, e1)) {
      for (const auto& entry : std::filesystem::directory_iterator(input, e1)) {
        std::error_code e2;
        if (std::filesystem::equivalent(output, entry.path(), e2)) {
          Fail("{} {} is one of the command's inputs (in {}): refusing to overwrite it", option,
               output, input);
        }
      }
    }
  }
}

void CreateDirectories(const std::string& path) {
  CheckNotProtected(path);
  std::error_code ec;
  std::filesystem::create_directories(path, ec);
  if (ec) Fail("{}: cannot create directory ({})", path, ec.message());
}

std::string JoinPaths(const std::string& a, const std::string& b) {
  return (std::filesystem::path(a) / b).string();
}

std::string UserCacheDirectory(const std::string& what) {
  std::string base;
  if (const char* d = std::getenv("XDG_CACHE_HOME"); d && *d) {
    base = d;
  } else if (const char* h = std::getenv("HOME"); h && *h) {
    base = JoinPaths(h, ".cache");
  } else {
    Fail("no cache folder: set XDG_CACHE_HOME or HOME");
  }
  std::filesystem::path dir = std::filesystem::path(base) / "linecloud";
  std::filesystem::path built;
  for (const auto& part : dir / what) {
    built /= part;
    if (::mkdir(built.c_str(), 0700) != 0 && errno != EEXIST) {
      Fail("{}: cannot create the cache folder ({})", built.string(), std::strerror(errno));
    }
  }
  for (const auto& p : {dir, dir / what}) {
    struct stat st;
    if (::lstat(p.c_str(), &st) != 0) Fail("{}: cannot read the cache folder", p.string());
    if (S_ISLNK(st.st_mode) || !S_ISDIR(st.st_mode)) {
      Fail("{}: the cache folder is a link or not a folder; remove it", p.string());
    }
    if (st.st_uid != ::geteuid()) Fail("{}: the cache folder belongs to another user", p.string());
    if ((st.st_mode & 022) != 0) {
      Fail("{}: others can write into the cache folder (mode {:o}); run chmod 700 on it",
           p.string(), st.st_mode & 0777);
    }
  }
  return (dir / what).string();
}

}  // namespace linecloud
