#include "linecloud/lifting/line_cloud.h"

#include <cmath>
#include <numbers>
#include <algorithm>

#include "linecloud/util/error.h"

namespace linecloud {

std::string_view LineEncodingName(LineEncoding encoding) {
  switch (encoding) {
    case LineEncoding::kPlucker:
      return "plucker-f64";
    case LineEncoding::kCompact:
      return "compact-256-f32";
  }
  return "unknown";
}

namespace {

struct CompactTable {
  std::array<Eigen::Vector3d, 256> directions;
  std::array<Eigen::Vector3d, 256> e1;
  std::array<Eigen::Vector3d, 256> e2;

  CompactTable() {
    // Fibonacci lattice on the hemisphere z > 0: equal-area rings in z,
    // golden-angle steps in azimuth.
    const double golden_angle = std::numbers::pi * (3.0 - std::sqrt(5.0));
    for (int i = 0; i < 256; ++i) {
      const double z = 1.0 - (i + 0.5) / 256.0;
      const double r = std::sqrt(1.0 - z * z);
      const double phi = golden_angle * i;
      directions[i] = Eigen::Vector3d(r * std::cos(phi), r * std::sin(phi), z);
      // e1 from the world axis least aligned with the direction.
      Eigen::Index axis;
      directions[i].cwiseAbs().minCoeff(&axis);
      const Eigen::Vector3d a = Eigen::Vector3d::Unit(axis);
      e1[i] = directions[i].cross(a).normalized();
      e2[i] = directions[i].cross(e1[i]);
    }
  }
};

const CompactTable& Table() {
  static const CompactTable table;
  return table;
}

}  // namespace

const std::array<Eigen::Vector3d, 256>& CompactDirections() { return Table().directions; }

void CompactBasis(uint8_t i, Eigen::Vector3d* e1, Eigen::Vector3d* e2) {
  *e1 = Table().e1[i];
  *e2 = Table().e2[i];
}

PluckerLine DecodeCompactLine(const CompactLine& c) {
  const CompactTable& t = Table();
  const Eigen::Vector3d& d = t.directions[c.direction_index];
  const Eigen::Vector3d anchor = static_cast<double>(c.position[0]) * t.e1[c.direction_index] +
                                 static_cast<double>(c.position[1]) * t.e2[c.direction_index];
  return PluckerLine(d, anchor.cross(d));
}

void LineCloud::Check(std::string_view source) const {
  if (lines.size() != ids.size()) {
    Fail("{}: {} lines but {} ids", source, lines.size(), ids.size());
  }
  if (encoding == LineEncoding::kCompact && compact.size() != ids.size()) {
    Fail("{}: {} compact lines but {} ids", source, compact.size(), ids.size());
  }
  if (descriptor_dim < 0 ||
      descriptors.size() != ids.size() * static_cast<size_t>(descriptor_dim)) {
    Fail("{}: descriptor block has {} bytes, expected {} x {}", source, descriptors.size(),
         ids.size(), descriptor_dim);
  }
  // Repeated ids: a linear scan when sorted (the usual case), else a sort.
  if (!std::is_sorted(ids.begin(), ids.end())) {
    std::vector<uint64_t> sorted = ids;
    std::sort(sorted.begin(), sorted.end());
    const auto dup = std::adjacent_find(sorted.begin(), sorted.end());
    if (dup != sorted.end()) Fail("{}: line id {} appears twice", source, *dup);
  } else {
    const auto dup = std::adjacent_find(ids.begin(), ids.end());
    if (dup != ids.end()) Fail("{}: line id {} appears twice", source, *dup);
  }
  for (size_t i = 0; i < ids.size(); ++i) {
    // A line farther than this from the origin is no map's: squared distances
    // would overflow (the attacks and the solvers square moments).
    if (lines[i].w.allFinite() && !(lines[i].w.stableNorm() <= kMaxLineDistance)) {
      Fail("{}: line {} (id {}) passes {:.3g} units from the origin (more than {:.0e}): not a map",
           source, i, ids[i], lines[i].w.stableNorm(), kMaxLineDistance);
    }
    if (!lines[i].IsValid(1e-6)) {
      Fail(
          "{}: line {} (id {}) is not a valid Plücker line (non-finite, "
          "non-unit direction, or moment not orthogonal to it)",
          source, i, ids[i]);
    }
  }
}

}  // namespace linecloud
