// The service's two kinds of threads: localization workers (a fixed pool
// behind a bounded queue) and request handlers (made on demand up to a
// bound, leaving when idle).
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

// The threads requests are handled on (serve/http): made as requests come,
// up to `max_threads` (then they wait in line), leaving when idle for
// `idle_exit`; at nice 10, below the localization workers (refusing a flood
// of bad requests must not take the CPU from poses). A handler may block
// until its request's deadline (waiting for a worker), never longer.
class RequestPool {
 public:
  RequestPool(int max_threads, std::chrono::milliseconds idle_exit);
  // Waits for every job submitted (each bounded by its request's deadline).
  ~RequestPool();
  RequestPool(const RequestPool&) = delete;
  RequestPool& operator=(const RequestPool&) = delete;
  void Submit(std::function<void()> job);
  // Jobs waiting or running.
  int busy() const;
  int threads() const;
  // Until no job waits or runs (every job submitted so far has returned).
  void WaitIdle() const;

 private:
  struct State;
  static void Loop(std::shared_ptr<State> state);
  std::shared_ptr<State> state_;  // shared with the threads, which leave on their own
};

}  // namespace linecloud
