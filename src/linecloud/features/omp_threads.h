// The calling thread's OpenMP team size for FAISS calls, restored on scope
// exit. OpenMP's nthreads setting belongs to the calling thread, so this does
// not change the team size of any other thread.
#pragma once

#include <omp.h>

namespace linecloud {

class OmpThreads {
 public:
  explicit OmpThreads(int threads) : before_(omp_get_max_threads()) {
    omp_set_num_threads(threads);
  }
  ~OmpThreads() { omp_set_num_threads(before_); }
  OmpThreads(const OmpThreads&) = delete;
  OmpThreads& operator=(const OmpThreads&) = delete;

 private:
  int before_;
};

}  // namespace linecloud
