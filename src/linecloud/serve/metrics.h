// The service's Prometheus metrics (text exposition format 0.0.4): requests
// by route and status, stage times, map load errors, and the gauges it is
// given (in flight, queued, maps) or reads itself (resident memory, SIFT's
// memory).
#pragma once

#include <cstdint>
#include <iterator>
#include <map>
#include <mutex>
#include <string>
#include <utility>

namespace linecloud {

// Prometheus counters and histograms (text exposition format 0.0.4).
class Metrics {
 public:
  static constexpr double kBucketsMs[] = {5, 10, 25, 50, 100, 250, 500, 1000, 2500, 5000, 10000};
  void Request(const std::string& route, int status) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++requests_[{route, status}];
  }
  void Stage(const std::string& stage, double ms) {
    std::lock_guard<std::mutex> lock(mutex_);
    Histogram& h = stages_[stage];
    for (size_t i = 0; i < std::size(kBucketsMs); ++i) h.buckets[i] += ms <= kBucketsMs[i];
    ++h.count;
    h.sum += ms;
  }
  void MapLoadError() {
    std::lock_guard<std::mutex> lock(mutex_);
    ++map_load_errors_;
  }
  std::string Text(int in_flight, int queued, size_t maps) const;

 private:
  struct Histogram {
    uint64_t buckets[std::size(kBucketsMs)] = {};
    uint64_t count = 0;
    double sum = 0;
  };
  mutable std::mutex mutex_;
  std::map<std::pair<std::string, int>, uint64_t> requests_;
  std::map<std::string, Histogram> stages_;
  uint64_t map_load_errors_ = 0;
};

}  // namespace linecloud
