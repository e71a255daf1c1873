#include "linecloud/serve/pools.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <utility>

namespace linecloud {

WorkPool::WorkPool(int threads, int capacity) : capacity_(capacity) {
  for (int i = 0; i < threads; ++i) workers_.emplace_back([this] { Loop(); });
}

WorkPool::~WorkPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
  for (std::thread& t : workers_) t.join();
}

bool WorkPool::TrySubmit(std::function<void()> job) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (static_cast<int>(jobs_.size()) >= capacity_ + idle_) return false;
    jobs_.push_back(std::move(job));
  }
  cv_.notify_one();
  return true;
}

int WorkPool::queued() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return std::max(0, static_cast<int>(jobs_.size()) - idle_);
}

void WorkPool::Loop() {
  for (;;) {
    std::function<void()> job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      ++idle_;
      cv_.wait(lock, [&] { return stopping_ || !jobs_.empty(); });
      --idle_;
      if (jobs_.empty()) return;  // stopping, and every job done
      job = std::move(jobs_.front());
      jobs_.pop_front();
    }
    ++running_;
    job();
    --running_;
  }
}

struct RequestPool::State {
  State(int max, std::chrono::milliseconds idle) : max_threads(max), idle_exit(idle) {}
  const int max_threads;
  const std::chrono::milliseconds idle_exit;
  mutable std::mutex mutex;
  mutable std::condition_variable work, done;
  std::deque<std::function<void()>> jobs;
  int threads = 0, idle = 0, running = 0;
  bool shutdown = false;
};

RequestPool::RequestPool(int max_threads, std::chrono::milliseconds idle_exit)
    : state_(std::make_shared<State>(max_threads, idle_exit)) {}

RequestPool::~RequestPool() {
  WaitIdle();
  std::unique_lock<std::mutex> lock(state_->mutex);
  state_->shutdown = true;
  state_->work.notify_all();
  state_->done.wait(lock, [&] { return state_->threads == 0; });
}

void RequestPool::Submit(std::function<void()> job) {
  bool spawn = false;
  {
    std::lock_guard<std::mutex> lock(state_->mutex);
    state_->jobs.push_back(std::move(job));
    if (static_cast<int>(state_->jobs.size()) > state_->idle &&
        state_->threads < state_->max_threads) {
      ++state_->threads;
      spawn = true;
    }
  }
  if (spawn) std::thread(Loop, state_).detach();
  state_->work.notify_one();
}

int RequestPool::busy() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return static_cast<int>(state_->jobs.size()) + state_->running;
}

int RequestPool::threads() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->threads;
}

void RequestPool::WaitIdle() const {
  std::unique_lock<std::mutex> lock(state_->mutex);
  state_->done.wait(lock, [&] { return state_->jobs.empty() && state_->running == 0; });
}

void RequestPool::Loop(std::shared_ptr<State> s) {
  ::setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), 10);
  for (;;) {
    std::function<void()> job;
    {
      std::unique_lock<std::mutex> lock(s->mutex);
      ++s->idle;
      const bool woken =
          s->work.wait_for(lock, s->idle_exit, [&] { return s->shutdown || !s->jobs.empty(); });
      --s->idle;
      if (s->jobs.empty()) {
        if (woken && !s->shutdown) continue;
        --s->threads;  // idle too long, or shutting down with nothing left
        s->done.notify_all();
        return;
      }
      job = std::move(s->jobs.front());
      s->jobs.pop_front();
      ++s->running;
    }
    job();
    std::lock_guard<std::mutex> lock(s->mutex);
    --s->running;
    s->done.notify_all();
  }
}

}  // namespace linecloud
