#include "linecloud/util/file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "linecloud/util/error.h"

namespace linecloud {

std::string ReadFileToString(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    Fail("{}: is a directory, expected a file", path);
  }
  std::ifstream file(path, std::ios::binary);
  if (!file) {
    Fail("{}: cannot open for reading ({})", path, std::strerror(errno));
  }
  std::string data;
  file.seekg(0, std::ios::end);
  const std::streamoff size = file.tellg();
  if (size < 0) Fail("{}: cannot determine file size", path);
  data.resize(static_cast<size_t>(size));
  file.seekg(0, std::ios::beg);
  file.read(data.data(), size);
  if (!file) Fail("{}: read error", path);
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

void WriteFileAtomically(const std::string& path,
                         const std::function<void(std::ostream&)>& write,
                         unsigned mode) {
  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  {
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC, mode);
    if (fd < 0) {
      Fail("{}: cannot create file ({})", path, std::strerror(errno));
    }
    ::fchmod(fd, mode);  // umask must not widen or narrow what we asked for
    ::close(fd);
  }
  try {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) Fail("{}: cannot open for writing", path);
    write(out);
    out.flush();
    if (!out) Fail("{}: write error (disk full?)", path);
  } catch (...) {
    std::remove(tmp.c_str());
    throw;
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string reason = std::strerror(errno);
    std::remove(tmp.c_str());
    Fail("{}: cannot move into place ({})", path, reason);
  }
}

void CreateDirectories(const std::string& path) {
  std::error_code ec;
  std::filesystem::create_directories(path, ec);
  if (ec) Fail("{}: cannot create directory ({})", path, ec.message());
}

std::string JoinPaths(const std::string& a, const std::string& b) {
  return (std::filesystem::path(a) / b).string();
}

}  // namespace linecloud
