#include "linecloud/util/log.h"
#include "linecloud/colmap/colmap_runner.h"

#include <fcntl.h>
#include <sys/prctl.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstring>
#include <sys/wait.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>

#include <fmt/core.h>
#include <sodium.h>

#include "linecloud/lifting/key.h"
#include "linecloud/util/clock.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace fs = std::filesystem;

namespace {

std::string LastLines(const std::string& path, int n) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty()) lines.push_back(line);
  }
  std::string out;
  for (size_t i = lines.size() > size_t(n) ? lines.size() - n : 0; i < lines.size(); ++i) {
    out += "\n  " + lines[i];
  }
  return out;
}

std::string ThreadsArg(const ColmapOptions& o) { return std::to_string(o.num_threads); }

}  // namespace

InputFingerprint::InputFingerprint() {
  EnsureSodiumInitialized();
  crypto_generichash_init(&state_, nullptr, 0, 32);
}

void InputFingerprint::Add(std::string_view s) {
  const uint64_t n = s.size();
  crypto_generichash_update(&state_, reinterpret_cast<const unsigned char*>(&n), sizeof(n));
  crypto_generichash_update(&state_, reinterpret_cast<const unsigned char*>(s.data()), s.size());
}

void InputFingerprint::AddFile(const std::string& path) { Add(ReadFileToString(path)); }

std::string InputFingerprint::Hex() {
  std::array<uint8_t, 32> out;
  crypto_generichash_final(&state_, out.data(), out.size());
  return ToHex(out);
}

std::string ColmapVersion(const ColmapOptions& options, const std::string& log_dir) {
  static std::mutex mutex;
  static std::map<std::string, std::string> known;
  std::lock_guard<std::mutex> lock(mutex);
  if (const auto it = known.find(options.executable); it != known.end()) return it->second;
  const std::string log = JoinPaths(log_dir, "colmap_version.log");
  RunColmapCommand({options.executable, "help"}, log,
                   ColmapOptions{.executable = options.executable});
  std::ifstream in(log);
  std::string line, version = "unknown";
  while (std::getline(in, line)) {
    if (line.find("COLMAP") != std::string::npos) {
      version = line;
      break;
    }
  }
  known[options.executable] = version;
  return version;
}

bool StampMatches(const std::string& path, const std::string& fingerprint) {
  return FileExists(path) && ReadFileToString(path) == fingerprint + "\n";
}

void WriteStamp(const std::string& path, const std::string& fingerprint) {
  WriteFileAtomically(path, [&](std::ostream& out) { out << fingerprint << "\n"; });
}

Reconstruction LargestModel(const std::string& sparse_dir) {
  Reconstruction best;
  if (!IsDirectory(sparse_dir)) return best;
  std::vector<fs::path> dirs;
  for (const auto& e : fs::directory_iterator(sparse_dir)) {
    if (e.is_directory()) dirs.push_back(e.path());
  }
  std::sort(dirs.begin(), dirs.end());
  for (const fs::path& dir : dirs) {
    Reconstruction model = ReadColmapModel(dir.string());
    if (model.images.size() > best.images.size()) best = std::move(model);
  }
  return best;
}

void CreateColmapDatabase(const std::string& path, const std::string& log_path,
                          const ColmapOptions& options) {
  fs::remove(path);
  RunColmapCommand({options.executable, "database_creator", "--database_path", path}, log_path,
                   options);
}

void ColmapOptions::Check() const {
  if (executable.empty()) Fail("colmap executable: empty path");
  if (num_threads == 0 || num_threads < -1)
    Fail("colmap threads: {} (use -1 for all cores)", num_threads);
}

void RunColmapCommand(const std::vector<std::string>& args, const std::string& log_path,
                      const ColmapOptions& options) {
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  // fork + exec rather than posix_spawn: the child asks to be killed with its
  // parent (PR_SET_PDEATHSIG), so that a `linecloud` killed mid-stage leaves
  // no COLMAP writing into the folder its re-run works in. Between fork and
  // exec only async-signal-safe calls.
  int error_pipe[2];
  if (pipe2(error_pipe, O_CLOEXEC) != 0) Fail("cannot run '{}': no pipe", args[0]);
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid < 0) {
    close(error_pipe[0]);
    close(error_pipe[1]);
    Fail("cannot run '{}': fork failed ({})", args[0], std::strerror(errno));
  }
  if (pid == 0) {
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(127);
    if (!options.verbose) {
      const int fd = open(log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
      if (fd < 0 || dup2(fd, 1) < 0 || dup2(fd, 2) < 0) {
        const int e = errno;
        (void)!write(error_pipe[1], &e, sizeof(e));
        _exit(127);
      }
    }
    execvp(argv[0], argv.data());
    const int e = errno;
    (void)!write(error_pipe[1], &e, sizeof(e));
    _exit(127);
  }
  close(error_pipe[1]);
  int child_errno = 0;
  const ssize_t got = read(error_pipe[0], &child_errno, sizeof(child_errno));
  close(error_pipe[0]);
  if (got == sizeof(child_errno)) {
    waitpid(pid, nullptr, 0);
    Fail("cannot run '{}': {} (install COLMAP: apt-get install colmap)", args[0],
         std::strerror(child_errno));
  }
  int status = 0;
  if (waitpid(pid, &status, 0) < 0) Fail("waiting for '{}' failed", args[0]);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    Fail("'{} {}' failed (exit status {}); log {}:{}", args[0], args.size() > 1 ? args[1] : "",
         WIFEXITED(status) ? WEXITSTATUS(status) : -1, log_path, LastLines(log_path, 8));
  }
}

Reconstruction ReconstructImageSubset(const std::string& database_path,
                                      const std::string& image_dir,
                                      const std::vector<std::string>& image_names,
                                      const std::string& out_dir, const ColmapOptions& options) {
  options.Check();
  CreateDirectories(out_dir);
  InputFingerprint fp;
  fp.Add(ReadFileToString(database_path));
  for (const std::string& n : image_names) fp.Add(n);
  const std::string fingerprint = fp.Hex();
  const std::string stamp = JoinPaths(out_dir, "fingerprint.txt");
  const std::string sparse = JoinPaths(out_dir, "sparse");
  if (StampMatches(stamp, fingerprint)) return LargestModel(sparse);
  fs::remove(stamp);
  fs::remove_all(sparse);
  CreateDirectories(sparse);
  const std::string list = JoinPaths(out_dir, "images.txt");
  WriteFileAtomically(list, [&](std::ostream& out) {
    for (const std::string& n : image_names) out << n << "\n";
  });
  // A query group spans a short baseline: the initial pair may triangulate
  // at 4° instead of COLMAP's 16° (which it relaxes to 8° at most).
  try {
    RunColmapCommand({options.executable,
                      "mapper",
                      "--database_path",
                      database_path,
                      "--image_path",
                      image_dir,
                      "--image_list_path",
                      list,
                      "--output_path",
                      sparse,
                      "--Mapper.num_threads",
                      ThreadsArg(options),
                      "--Mapper.min_model_size",
                      "2",
                      "--Mapper.init_min_tri_angle",
                      "4",
                      "--Mapper.ba_refine_focal_length",
                      "0",
                      "--Mapper.ba_refine_principal_point",
                      "0",
                      "--Mapper.ba_refine_extra_params",
                      "0"},
                     JoinPaths(out_dir, "mapper.log"), options);
  } catch (const Error&) {
    // No model (e.g. no initial pair): a result too, cached like any other.
    fs::remove_all(sparse);
    CreateDirectories(sparse);
  }
  WriteStamp(stamp, fingerprint);
  return LargestModel(sparse);
}

}  // namespace linecloud
