// A minimal parallel loop over [0, n) on a few threads (std::thread), for the
// brute-force searches of privacy/: rows are handed out in chunks through an
// atomic counter; the calling thread reports progress while the workers run.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace linecloud {

// Number of worker threads for `requested` (<= 0: the machine's cores).
inline int WorkerThreads(int requested) {
  if (requested > 0) return requested;
  return std::max(1u, std::thread::hardware_concurrency());
}

// Calls body(i, worker) for every i in [0, n), worker in [0, threads).
// progress(done, n) is called from the calling thread about every
// `progress_interval_s` seconds. The first exception thrown by a body is
// rethrown after all workers stopped.
inline void ParallelFor(size_t n, int threads, const std::function<void(size_t, int)>& body,
                        const std::function<void(size_t, size_t)>& progress = nullptr,
                        double progress_interval_s = 1.0) {
  threads = static_cast<int>(std::min<size_t>(WorkerThreads(threads), std::max<size_t>(n, 1)));
  const size_t chunk = std::clamp<size_t>(n / (static_cast<size_t>(threads) * 64), 1, 256);
  std::atomic<size_t> next{0}, done{0};
  std::atomic<bool> failed{false};
  std::exception_ptr error;
  std::mutex error_mutex;
  auto work = [&](int worker) {
    try {
      while (!failed.load(std::memory_order_relaxed)) {
        const size_t begin = next.fetch_add(chunk);
        if (begin >= n) break;
        const size_t end = std::min(n, begin + chunk);
        for (size_t i = begin; i < end; ++i) body(i, worker);
        done.fetch_add(end - begin);
      }
    } catch (...) {
      std::lock_guard<std::mutex> lock(error_mutex);
      if (!error) error = std::current_exception();
      failed = true;
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(work, t);
  if (!progress) {
    work(0);
  } else {
    // The calling thread only reports: workers do the rows.
    pool.emplace_back(work, 0);
    const auto start = std::chrono::steady_clock::now();
    double next_report = progress_interval_s;
    while (done.load() < n && !failed.load()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      const double elapsed =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (elapsed >= next_report) {
        progress(done.load(), n);
        next_report = elapsed + progress_interval_s;
      }
    }
  }
  for (std::thread& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

}  // namespace linecloud
