// PLY export for viewing in MeshLab / CloudCompare (binary little-endian).
#pragma once

#include <string>

#include "linecloud/io/colmap_model.h"
#include "linecloud/lifting/line_cloud.h"

namespace linecloud {

// Each line as a segment of `segment_length` centred on its anchor (the point
// of the line closest to the origin — the only point a line cloud knows):
// two vertices per line and one `edge` element joining them.
// segment_length <= 0 picks 5% of the anchors' bounding-box diagonal.
void WriteLineCloudPly(const LineCloud& cloud, const std::string& path,
                       double segment_length);

// The model's 3D points with their colours.
void WriteModelPly(const Reconstruction& reconstruction, const std::string& path);

// Axis-aligned bounding box of the line anchors (min, max).
void AnchorBoundingBox(const LineCloud& cloud, Eigen::Vector3d* min,
                       Eigen::Vector3d* max);

}  // namespace linecloud
