// Wall-clock seconds since a time point (stage timings, progress).
#pragma once

#include <chrono>

namespace linecloud {

inline double SecondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

inline double MsSince(std::chrono::steady_clock::time_point t0) { return 1e3 * SecondsSince(t0); }

}  // namespace linecloud
