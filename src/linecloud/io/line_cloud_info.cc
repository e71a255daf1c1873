#include "linecloud/io/line_cloud_info.h"

#include <Eigen/Core>

#include "linecloud/io/lcm_format.h"
#include "linecloud/io/ply.h"
#include "linecloud/lifting/key.h"

namespace linecloud {

nlohmann::json LineCloudInfo(const LineCloud& cloud, const std::string& file,
                             uintmax_t file_bytes) {
  Eigen::Vector3d min, max;
  AnchorBoundingBox(cloud, &min, &max);
  nlohmann::json j;
  if (!file.empty()) {
    j["file"] = file;
    j["file_bytes"] = file_bytes;
  }
  j["format_version"] = cloud.keyed_line_ids ? kLcmVersion : 1;
  j["num_lines"] = cloud.size();
  j["encoding"] = std::string(LineEncodingName(cloud.encoding));
  if (!file.empty()) {
    j["bytes_per_line"] = cloud.size() ? static_cast<double>(file_bytes) / cloud.size() : 0.0;
  }
  j["has_descriptors"] = cloud.has_descriptors();
  if (cloud.has_descriptors()) {
    j["descriptors"] = {{"dim", cloud.descriptor_dim},
                        {"type", cloud.descriptor_type},
                        {"aggregation", cloud.descriptor_aggregation}};
  }
  j["key_fingerprint"] = ToHex(cloud.key_fingerprint);
  if (cloud.gravity) j["gravity"] = {cloud.gravity->x(), cloud.gravity->y(), cloud.gravity->z()};
  j["anchor_bbox"] = {{"min", {min.x(), min.y(), min.z()}}, {"max", {max.x(), max.y(), max.z()}}};
  return j;
}

}  // namespace linecloud
