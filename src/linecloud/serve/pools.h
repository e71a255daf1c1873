// The service's two kinds of threads: localization workers (a fixed pool
// behind a bounded queue) and connection threads for cpp-httplib (made on
// demand up to a bound, leaving when idle).
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include <httplib.h>

namespace linecloud {

// A fixed pool of localization workers behind a bounded queue.
class WorkPool {
 public:
  WorkPool(int threads, int capacity);
  ~WorkPool();
  WorkPool(const WorkPool&) = delete;
  WorkPool& operator=(const WorkPool&) = delete;
  // False when every idle worker has a job and `capacity` more wait.
  bool TrySubmit(std::function<void()> job);
  int queued() const;
  int running() const { return running_.load(); }

 private:
  void Loop();
  const int capacity_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> jobs_;
  std::vector<std::thread> workers_;
  std::atomic<int> running_{0};
  int idle_ = 0;  // workers waiting for a job
  bool stopping_ = false;
};

// cpp-httplib's task queue: each accepted connection is read on a thread of
// its own for as long as it lasts — a client that dribbles its request holds
// one. The library's ThreadPool makes a fixed number at start, so 64 such
// clients left no thread for anyone else; here a connection that finds no
// idle thread gets a new one, up to `max_threads` (then it waits for one),
// and a thread idle for `idle_exit` leaves. shutdown() answers what was
// accepted, but waits at most `drain` for connections still open (a client
// that never finishes its request would hold it for ever).
class ConnectionPool : public httplib::TaskQueue {
 public:
  ConnectionPool(int max_threads, std::chrono::milliseconds idle_exit,
                 std::chrono::milliseconds drain);
  void enqueue(std::function<void()> fn) override;
  void shutdown() override;
  int threads() const;

 private:
  struct State;
  static void Loop(std::shared_ptr<State> state);
  std::shared_ptr<State> state_;  // shared with the threads: they may outlive a drain
  const std::chrono::milliseconds drain_;
};

}  // namespace linecloud
