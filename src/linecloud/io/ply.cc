#include "linecloud/io/ply.h"

#include <bit>
#include <cmath>

#include <sstream>

#include <cstring>

#include <array>
#include <ostream>
#include <utility>
#include <vector>

#include "linecloud/util/byte_reader.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {

void AnchorBoundingBox(const LineCloud& cloud, Eigen::Vector3d* min, Eigen::Vector3d* max) {
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

void WriteLineCloudPly(const LineCloud& cloud, const std::string& path, double segment_length) {
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

void WritePointsPly(const std::string& path, const std::vector<Eigen::Vector3d>& points,
                    const std::vector<std::array<uint8_t, 3>>& colors, const std::string& comment,
                    unsigned mode) {
  if (!colors.empty() && colors.size() != points.size()) {
    Fail("{}: {} colours for {} points", path, colors.size(), points.size());
  }
  WriteFileAtomically(
      path,
      [&](std::ostream& out) {
        out << "ply\nformat binary_little_endian 1.0\n";
        if (!comment.empty()) out << "comment " << comment << "\n";
        out << "element vertex " << points.size() << "\n"
            << "property float x\nproperty float y\nproperty float z\n";
        if (!colors.empty())
          out << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
        out << "end_header\n";
        for (size_t i = 0; i < points.size(); ++i) {
          for (int k = 0; k < 3; ++k) WriteLE(out, static_cast<float>(points[i][k]));
          if (!colors.empty()) out.write(reinterpret_cast<const char*>(colors[i].data()), 3);
        }
      },
      mode);
}

void ReadColoredPointsPly(const std::string& path, size_t max_points, std::vector<float>* xyz,
                          std::vector<uint8_t>* rgb) {
  const std::string data = ReadFileToString(path);
  const size_t end = data.find("end_header\n");
  if (data.rfind("ply\nformat binary_little_endian 1.0\n", 0) != 0 || end == std::string::npos) {
    Fail("{}: not a binary little-endian PLY file", path);
  }
  std::istringstream header(data.substr(0, end));
  std::string line, properties;
  size_t n = 0;
  bool counted = false;
  while (std::getline(header, line)) {
    if (line.rfind("element vertex ", 0) == 0) {
      const std::string count = line.substr(15);
      if (count.empty() || count.size() > 12 ||
          count.find_first_not_of("0123456789") != std::string::npos) {
        Fail("{}: bad vertex count", path);
      }
      n = std::stoull(count);
      counted = true;
    } else if (line.rfind("property ", 0) == 0) {
      properties += line + "\n";
    } else if (line.rfind("element ", 0) == 0) {
      Fail("{}: only vertices expected", path);
    }
  }
  if (!counted || properties !=
                      "property float x\nproperty float y\nproperty float z\n"
                      "property uchar red\nproperty uchar green\nproperty uchar blue\n") {
    Fail("{}: expected vertices of float x, y, z and uchar red, green, blue", path);
  }
  if (n > max_points) Fail("{}: {} points, more than {}", path, n, max_points);
  const size_t body = end + 11;
  if (data.size() - body != n * 15) {
    Fail("{}: {} bytes of vertices, {} points need {}", path, data.size() - body, n, n * 15);
  }
  xyz->resize(3 * n);
  rgb->resize(3 * n);
  for (size_t i = 0; i < n; ++i) {
    static_assert(std::endian::native == std::endian::little, "PLY floats are read as stored");
    std::memcpy(xyz->data() + 3 * i, data.data() + body + 15 * i, 12);
    std::memcpy(rgb->data() + 3 * i, data.data() + body + 15 * i + 12, 3);
    for (int k = 0; k < 3; ++k) {
      if (!std::isfinite((*xyz)[3 * i + k])) Fail("{}: point {} is not finite", path, i);
    }
  }
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

void WriteLocalizationPly(const std::string& path, const LineCloud* cloud,
                          const Reconstruction* model, const std::vector<PlyCamera>& cameras,
                          double depth) {
  struct Vertex {
    Eigen::Vector3d p;
    std::array<uint8_t, 3> rgb;
  };
  std::vector<Vertex> vertices;
  std::vector<std::pair<int32_t, int32_t>> edges;
  Eigen::Vector3d min = Eigen::Vector3d::Zero(), max = Eigen::Vector3d::Zero();
  if (cloud) {
    AnchorBoundingBox(*cloud, &min, &max);
    const double length = 0.05 * (max - min).norm();
    for (const PluckerLine& line : cloud->lines) {
      edges.emplace_back(static_cast<int32_t>(vertices.size()),
                         static_cast<int32_t>(vertices.size() + 1));
      for (const double s : {-0.5, 0.5}) {
        vertices.push_back({line.PointAt(s * length), {160, 160, 160}});
      }
    }
  }
  if (model) {
    bool first = true;
    for (const uint64_t id : model->SortedPoint3DIds()) {
      const Point3D& p = model->points3D.at(id);
      vertices.push_back({p.xyz, p.color});
      min = first ? p.xyz : Eigen::Vector3d(min.cwiseMin(p.xyz));
      max = first ? p.xyz : Eigen::Vector3d(max.cwiseMax(p.xyz));
      first = false;
    }
  }
  if (!(depth > 0)) depth = 0.1 * (max - min).norm();
  if (!(depth > 0)) depth = 1.0;
  for (const PlyCamera& c : cameras) {
    const int32_t centre = static_cast<int32_t>(vertices.size());
    // Distances in the camera frame are scale × world distances.
    const double d = depth / c.world_from_cam.scale;
    vertices.push_back({c.world_from_cam * Eigen::Vector3d::Zero(), {230, 30, 30}});
    const double w = static_cast<double>(c.camera.width), h = static_cast<double>(c.camera.height);
    for (const Eigen::Vector2d& corner : {Eigen::Vector2d(0, 0), Eigen::Vector2d(w, 0),
                                          Eigen::Vector2d(w, h), Eigen::Vector2d(0, h)}) {
      vertices.push_back({c.world_from_cam * (d * c.camera.CamFromImg(corner)), {230, 30, 30}});
    }
    for (int k = 0; k < 4; ++k) {
      edges.emplace_back(centre, centre + 1 + k);
      edges.emplace_back(centre + 1 + k, centre + 1 + (k + 1) % 4);
    }
  }
  for (const Vertex& v : vertices) {
    if (!v.p.allFinite()) Fail("{}: a vertex to write is not finite", path);
  }
  WriteFileAtomically(path, [&](std::ostream& out) {
    out << "ply\nformat binary_little_endian 1.0\n"
        << "comment linecloud localization: the map and the localized camera(s), red\n"
        << "element vertex " << vertices.size() << "\n"
        << "property float x\nproperty float y\nproperty float z\n"
        << "property uchar red\nproperty uchar green\nproperty uchar blue\n"
        << "element edge " << edges.size() << "\n"
        << "property int vertex1\nproperty int vertex2\n"
        << "end_header\n";
    for (const Vertex& v : vertices) {
      for (int k = 0; k < 3; ++k) WriteLE(out, static_cast<float>(v.p[k]));
      for (int k = 0; k < 3; ++k) WriteLE(out, v.rgb[k]);
    }
    for (const auto& [a, b] : edges) {
      WriteLE(out, a);
      WriteLE(out, b);
    }
  });
}

}  // namespace linecloud
