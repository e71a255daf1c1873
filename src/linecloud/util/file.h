// Small file helpers: whole-file reads with clear errors and atomic writes
// (write to a temporary sibling, then rename), so that a failing command never
// leaves a partial output file behind.
#pragma once

#include <cstdint>
#include <functional>
#include <ostream>
#include <string>
#include <vector>

namespace linecloud {

// Reads the whole file; throws Error naming the path if it cannot be read.
std::string ReadFileToString(const std::string& path);

bool FileExists(const std::string& path);
bool IsDirectory(const std::string& path);

// Calls `write` with a binary stream on a temporary file next to `path` and
// renames it to `path` only if `write` returned without throwing and the
// stream is good. `mode` are the permission bits of the created file.
void WriteFileAtomically(const std::string& path,
                         const std::function<void(std::ostream&)>& write,
                         unsigned mode = 0644);

// Creates a directory and its parents; throws Error naming the path on failure.
void CreateDirectories(const std::string& path);

std::string JoinPaths(const std::string& a, const std::string& b);

}  // namespace linecloud
