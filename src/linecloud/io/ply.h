// PLY export for viewing in MeshLab / CloudCompare (binary little-endian).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "linecloud/geometry/rigid3.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/lifting/line_cloud.h"

namespace linecloud {

// Each line as a segment of `segment_length` centred on its anchor (the point
// of the line closest to the origin — the only point a line cloud knows):
// two vertices per line and one `edge` element joining them.
// segment_length <= 0 picks 5% of the anchors' bounding-box diagonal.
void WriteLineCloudPly(const LineCloud& cloud, const std::string& path, double segment_length);

// The model's 3D points with their colours.
void WriteModelPly(const Reconstruction& reconstruction, const std::string& path);

// Points, optionally coloured (`colors` empty or one RGB triple per point).
// `mode` as WriteFileAtomically's (0600 for points recovered from a map).
void WritePointsPly(const std::string& path, const std::vector<Eigen::Vector3d>& points,
                    const std::vector<std::array<uint8_t, 3>>& colors, const std::string& comment,
                    unsigned mode = 0644);

// Reads back what WritePointsPly wrote with colours (binary little-endian,
// float x y z, uchar red green blue): xyz N x 3, rgb N x 3. Throws Error
// naming `path` for anything else, a truncated file or more than
// `max_points` points.
void ReadColoredPointsPly(const std::string& path, size_t max_points, std::vector<float>* xyz,
                          std::vector<uint8_t>* rgb);

// A localized camera to draw: its frustum (centre and the rays through the
// image corners, cut at `depth` world units) in world coordinates.
struct PlyCamera {
  Sim3d world_from_cam;  // may carry a scale (+s methods)
  Camera camera;
};

// The map (line segments as in WriteLineCloudPly, grey, or a point model's
// coloured points) and each camera's frustum (red: 5 vertices, 8 edges), so
// that a viewer shows where the query was localized. `depth` <= 0 picks 10 %
// of the map's bounding-box diagonal.
void WriteLocalizationPly(const std::string& path, const LineCloud* cloud,
                          const Reconstruction* model, const std::vector<PlyCamera>& cameras,
                          double depth);

// Axis-aligned bounding box of the line anchors (min, max).
void AnchorBoundingBox(const LineCloud& cloud, Eigen::Vector3d* min, Eigen::Vector3d* max);

}  // namespace linecloud
