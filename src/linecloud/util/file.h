// Small file helpers: whole-file reads with clear errors and atomic writes
// (write to a temporary sibling, then rename), so that a failing command never
// leaves a partial output file behind.
#pragma once

#include <cstdint>
#include <functional>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>

namespace linecloud {

// Throws Error naming the path unless it is a readable regular file (after
// links): directories, devices, FIFOs (which would block) and sockets are refused.
void CheckReadableFile(const std::string& path);

// Reads the whole file (CheckReadableFile first); throws Error naming the path
// if it cannot be read.
std::string ReadFileToString(const std::string& path);

// At most the first `max_bytes` of the file (CheckReadableFile first): a
// format's magic and header can be checked before a large file is read.
std::string ReadFilePrefix(const std::string& path, size_t max_bytes);

bool FileExists(const std::string& path);

// The process umask, read without changing it (Linux: /proc/self/status).
unsigned CurrentUmask();
bool IsDirectory(const std::string& path);

// Calls `write` on an in-memory stream, then, only if it returned without
// throwing: for a regular file (or none), writes an exclusive temporary file
// (mkstemp, flock'ed while written) in the same folder, fsyncs it and renames
// it over the target; through a symbolic link, replaces the file the link
// names (the link stays); a device or FIFO (/dev/null, /dev/stdout) is
// written through, never replaced, and a FIFO nothing reads is refused instead
// of blocking. Modes: a new file gets `mode` less the process umask (as
// open(2)); a replaced file keeps its mode, narrowed to `mode` (so secrets
// written 0600 stay 0600). Temporaries of a writer killed mid-write (older
// than a minute, unlocked) are removed on the next write into that folder.
// Throws Error naming the path on any failure, leaving no file.
void WriteFileAtomically(const std::string& path, const std::function<void(std::ostream&)>& write,
                         unsigned mode = 0644);

// Creates `path` exclusively (O_EXCL; a link at its name is not followed) with
// exactly `mode`, writes `text` and syncs it: for secrets that must never
// replace a file. Returns false, touching nothing, when something exists at
// `path`; throws Error ("PATH: cannot create/write WHAT") on any other failure,
// leaving no file.
bool WriteNewFile(const std::string& path, std::string_view text, unsigned mode,
                  std::string_view what);

// Throws Error when `output` exists and is one of `inputs` (the same file by
// any path or link) or a file directly inside an input folder. `option` names
// the output option in the message (e.g. "--out").
void RefuseOutputOverInputs(const std::string& output, const std::vector<std::string>& inputs,
                            const std::string& option);

// Folders no output may be written into: key stores (a key or ledger written
// over is lost). WriteFileAtomically, WriteNewFile and CreateDirectories
// refuse a target inside one, after links, unless a ProtectedWriteScope is
// alive on the calling thread (the key store's own writes).
void ProtectDirectory(const std::string& dir);
void CheckNotProtected(const std::string& path);
class ProtectedWriteScope {
 public:
  ProtectedWriteScope();
  ~ProtectedWriteScope();
  ProtectedWriteScope(const ProtectedWriteScope&) = delete;
  ProtectedWriteScope& operator=(const ProtectedWriteScope&) = delete;
};

// This user's cache folder for `what` ($XDG_CACHE_HOME/linecloud/WHAT, else
// ~/.cache/linecloud/WHAT), created mode 0700; refused (Error) when it is a
// link, another user's, or open to others — caches are never written where
// someone else could plant a link or a FIFO.
std::string UserCacheDirectory(const std::string& what);

// Creates a directory and its parents; throws Error naming the path on failure.
void CreateDirectories(const std::string& path);

std::string JoinPaths(const std::string& a, const std::string& b);

}  // namespace linecloud
