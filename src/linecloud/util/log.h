// One sink for what library code says while it works: progress on long work (COLMAP, eval, the
// key sweep) and warnings that do not stop it (a world-readable key file, a skipped key-store
// entry). Results never go through it; errors are thrown or returned as statuses.
//
// By default progress goes to stdout and warnings to stderr, each as one line. A caller redirects
// both with SetLogSink (the Python module hands them to a Python callable; a test collects them)
// and silences them with SetLogSink(SilentLog()). The sink is process-wide, like COLMAP's glog; it
// is called from any thread, possibly from several at once (a sink that collects locks; Python's
// is serialised by the GIL). The default sink writes whole lines.
#pragma once

#include <fmt/format.h>

#include <functional>
#include <string>
#include <string_view>
#include <utility>

namespace linecloud {

enum class LogLevel { kProgress, kWarning };

std::string_view LogLevelName(LogLevel level);  // "progress" | "warning"

using LogSink = std::function<void(LogLevel, std::string_view)>;

// Replaces the sink (an empty function restores the default) and returns the one it replaced.
LogSink SetLogSink(LogSink sink);

// A sink that drops everything.
LogSink SilentLog();

// Hands one line (no trailing newline) to the sink.
void Log(LogLevel level, std::string_view line);

template <typename... Args>
void LogProgress(fmt::format_string<Args...> format, Args&&... args) {
  Log(LogLevel::kProgress, fmt::format(format, std::forward<Args>(args)...));
}

template <typename... Args>
void LogWarning(fmt::format_string<Args...> format, Args&&... args) {
  Log(LogLevel::kWarning, fmt::format(format, std::forward<Args>(args)...));
}

// Sets a sink for the lifetime of the object, then puts the previous one back (tests).
class ScopedLogSink {
 public:
  explicit ScopedLogSink(LogSink sink) : previous_(SetLogSink(std::move(sink))) {}
  ~ScopedLogSink() { SetLogSink(std::move(previous_)); }
  ScopedLogSink(const ScopedLogSink&) = delete;
  ScopedLogSink& operator=(const ScopedLogSink&) = delete;

 private:
  LogSink previous_;
};

}  // namespace linecloud
