#include "linecloud/util/log.h"

#include <cstdio>
#include <mutex>

namespace linecloud {
namespace {

std::mutex& SinkMutex() {
  static std::mutex mutex;
  return mutex;
}

LogSink& CurrentSink() {
  static LogSink sink;
  return sink;
}

void DefaultSink(LogLevel level, std::string_view line) {
  std::FILE* out = level == LogLevel::kWarning ? stderr : stdout;
  if (level == LogLevel::kWarning) std::fputs("warning: ", out);
  std::fwrite(line.data(), 1, line.size(), out);
  std::fputc('\n', out);
  std::fflush(out);
}

}  // namespace

std::string_view LogLevelName(LogLevel level) {
  return level == LogLevel::kWarning ? "warning" : "progress";
}

LogSink SetLogSink(LogSink sink) {
  std::lock_guard<std::mutex> lock(SinkMutex());
  LogSink previous = std::move(CurrentSink());
  CurrentSink() = std::move(sink);
  return previous;
}

LogSink SilentLog() {
  return [](LogLevel, std::string_view) {};
}

void Log(LogLevel level, std::string_view line) {
  std::lock_guard<std::mutex> lock(SinkMutex());
  if (CurrentSink()) {
    CurrentSink()(level, line);
  } else {
    DefaultSink(level, line);
  }
}

}  // namespace linecloud
