#include "linecloud/io/ply.h"

#include <ostream>

#include "linecloud/util/byte_reader.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {

void AnchorBoundingBox(const LineCloud& cloud, Eigen::Vector3d* min,
                       Eigen::Vector3d* max) {
  *min = Eigen::Vector3d::Zero();
  *max = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d a = cloud.lines[i].Anchor();
    if (i == 0) {
      *min = *max = a;
    } else {
      *min = min->cwiseMin(a);
      *max = max->cwiseMax(a);
    }
  }
}

void WriteLineCloudPly(const LineCloud& cloud, const std::string& path,
                       double segment_length) {
  if (!std::isfinite(segment_length)) Fail("--segment-length must be finite");
  if (segment_length <= 0) {
    Eigen::Vector3d min, max;
    AnchorBoundingBox(cloud, &min, &max);
    segment_length = 0.05 * (max - min).norm();
    if (segment_length <= 0) segment_length = 1.0;
  }
  WriteFileAtomically(path, [&](std::ostream& out) {
    out << "ply\nformat binary_little_endian 1.0\n"
        << "comment linecloud line cloud: one segment per line, centred on "
           "the line's point closest to the origin\n"
        << "element vertex " << 2 * cloud.size() << "\n"
        << "property float x\nproperty float y\nproperty float z\n"
        << "element edge " << cloud.size() << "\n"
        << "property int vertex1\nproperty int vertex2\n"
        << "end_header\n";
    for (const PluckerLine& line : cloud.lines) {
      for (const double s : {-0.5, 0.5}) {
        const Eigen::Vector3d p = line.PointAt(s * segment_length);
        for (int k = 0; k < 3; ++k) WriteLE(out, static_cast<float>(p[k]));
      }
    }
    for (size_t i = 0; i < cloud.size(); ++i) {
      WriteLE(out, static_cast<int32_t>(2 * i));
      WriteLE(out, static_cast<int32_t>(2 * i + 1));
    }
  });
}

void WriteModelPly(const Reconstruction& rec, const std::string& path) {
  WriteFileAtomically(path, [&](std::ostream& out) {
    out << "ply\nformat binary_little_endian 1.0\n"
        << "element vertex " << rec.points3D.size() << "\n"
        << "property float x\nproperty float y\nproperty float z\n"
        << "property uchar red\nproperty uchar green\nproperty uchar blue\n"
        << "end_header\n";
    for (const uint64_t id : rec.SortedPoint3DIds()) {
      const Point3D& p = rec.points3D.at(id);
      for (int k = 0; k < 3; ++k) WriteLE(out, static_cast<float>(p.xyz[k]));
      for (int k = 0; k < 3; ++k) WriteLE(out, p.color[k]);
    }
  });
}

}  // namespace linecloud
