#include "linecloud/util/log.h"

#include <gtest/gtest.h>

#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace linecloud {
namespace {

TEST(Log, ASinkGetsEveryLineFromEveryThreadAndTheDefaultComesBack) {
  std::vector<std::string> lines;
  std::mutex mutex;
  {
    ScopedLogSink sink([&](LogLevel level, std::string_view line) {
      std::lock_guard<std::mutex> lock(mutex);
      lines.push_back(std::string(LogLevelName(level)) + ": " + std::string(line));
    });
    LogProgress("step {} of {}", 1, 2);
    LogWarning("{} skipped", "entry");
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t) {
      threads.emplace_back([t] {
        for (int i = 0; i < 100; ++i) LogProgress("thread {} line {}", t, i);
      });
    }
    for (std::thread& thread : threads) thread.join();
  }
  ASSERT_EQ(lines.size(), 402u);  // none lost
  EXPECT_EQ(lines[0], "progress: step 1 of 2");
  EXPECT_EQ(lines[1], "warning: entry skipped");
  // The scope ended: the previous (default) sink is back, ours gets nothing more.
  testing::internal::CaptureStdout();
  testing::internal::CaptureStderr();
  LogProgress("after");
  LogWarning("careful");
  EXPECT_EQ(testing::internal::GetCapturedStdout(), "after\n");
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "warning: careful\n");
  EXPECT_EQ(lines.size(), 402u);
}

TEST(Log, TheSilentSinkSaysNothing) {
  ScopedLogSink silent(SilentLog());
  testing::internal::CaptureStdout();
  testing::internal::CaptureStderr();
  LogProgress("hidden");
  LogWarning("hidden too");
  EXPECT_EQ(testing::internal::GetCapturedStdout(), "");
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
}

}  // namespace
}  // namespace linecloud
