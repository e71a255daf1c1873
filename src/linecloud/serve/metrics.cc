#include "linecloud/serve/metrics.h"

#include <fmt/format.h>

#include "linecloud/features/sift_scale_space.h"
#include "linecloud/util/memory.h"

namespace linecloud {

std::string Metrics::Text(int in_flight, int queued, size_t maps) const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::string out =
      "# HELP linecloud_requests_total Requests answered, by route and status.\n"
      "# TYPE linecloud_requests_total counter\n";
  for (const auto& [key, n] : requests_) {
    out += fmt::format("linecloud_requests_total{{route=\"{}\",status=\"{}\"}} {}\n", key.first,
                       key.second, n);
  }
  out +=
      "# HELP linecloud_stage_ms Localization time per stage, milliseconds.\n"
      "# TYPE linecloud_stage_ms histogram\n";
  for (const auto& [stage, h] : stages_) {
    for (size_t i = 0; i < std::size(kBucketsMs); ++i) {
      out += fmt::format("linecloud_stage_ms_bucket{{stage=\"{}\",le=\"{}\"}} {}\n", stage,
                         kBucketsMs[i], h.buckets[i]);
    }
    out +=
        fmt::format("linecloud_stage_ms_bucket{{stage=\"{}\",le=\"+Inf\"}} {}\n", stage, h.count);
    out += fmt::format("linecloud_stage_ms_sum{{stage=\"{}\"}} {}\n", stage, h.sum);
    out += fmt::format("linecloud_stage_ms_count{{stage=\"{}\"}} {}\n", stage, h.count);
  }
  out += fmt::format(
      "# TYPE linecloud_in_flight gauge\nlinecloud_in_flight {}\n"
      "# TYPE linecloud_queue_length gauge\nlinecloud_queue_length {}\n"
      "# TYPE linecloud_maps gauge\nlinecloud_maps {}\n"
      "# HELP linecloud_map_load_errors_total Map files (or the folder) that did not load.\n"
      "# TYPE linecloud_map_load_errors_total counter\nlinecloud_map_load_errors_total {}\n"
      "# TYPE linecloud_resident_bytes gauge\nlinecloud_resident_bytes {}\n",
      in_flight, queued, maps, map_load_errors_, ResidentBytes());
  const SiftMemoryUse sift = SiftMemoryInUse();
  out += fmt::format(
      "# HELP linecloud_sift_memory_bytes SIFT's scale space: reserved by running "
      "extractions, pooled for the next, the limit (--memory-budget-mb).\n"
      "# TYPE linecloud_sift_memory_bytes gauge\n"
      "linecloud_sift_memory_bytes{{kind=\"reserved\"}} {}\n"
      "linecloud_sift_memory_bytes{{kind=\"pooled\"}} {}\n"
      "linecloud_sift_memory_bytes{{kind=\"limit\"}} {}\n",
      sift.reserved, sift.pooled, sift.limit);
  return out;
}

}  // namespace linecloud
