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
  LogSink sink;
  {
    std::lock_guard<std::mutex> lock(SinkMutex());
    sink = CurrentSink();
  }
  // Called outside the lock: a sink that waits for something (Python's GIL) held by a thread
  // about to log or to change the sink cannot deadlock with it.
  if (sink) {
    sink(level, line);
  } else {
    static std::mutex default_mutex;  // whole lines on the console
    std::lock_guard<std::mutex> lock(default_mutex);
    DefaultSink(level, line);
  }
}

}  // namespace linecloud
