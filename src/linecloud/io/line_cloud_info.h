// What `linecloud info --json` prints about a map, as a library call (the CLI,
// the Python binding and the service describe a map the same way).
#pragma once

#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "linecloud/lifting/line_cloud.h"

namespace linecloud {

// {"file", "file_bytes", "format_version", "num_lines", "encoding",
//  "bytes_per_line", "has_descriptors", "descriptors" (when present),
//  "key_fingerprint", "gravity" (when known), "anchor_bbox"}. `file` empty and
// `file_bytes` 0 for a map that is not (yet) a file: those two fields and
// bytes_per_line are left out.
nlohmann::json LineCloudInfo(const LineCloud& cloud, const std::string& file = "",
                             uintmax_t file_bytes = 0);

}  // namespace linecloud
