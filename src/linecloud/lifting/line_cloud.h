// A line cloud: the privacy-preserving map. It holds lines, the ids of the
// points they were lifted from, and optional descriptors — and by construction
// nothing else: there is no field that could carry point coordinates, colours,
// track lengths or errors. The only function that sees points and lines
// together is the lifting (lifting.h).
#pragma once

#include <array>
#include <optional>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "linecloud/geometry/plucker.h"

namespace linecloud {

enum class LineEncoding : uint8_t {
  // (v, w) as six float64: 48 bytes per line, exact.
  kPlucker = 0,
  // The paper's compact form: one of 256 fixed directions (1 byte) and the
  // line's 2D position in the plane through the origin orthogonal to it
  // (2 float32): 9 bytes per line.
  kCompact = 1,
};

std::string_view LineEncodingName(LineEncoding encoding);

struct CompactLine {
  uint8_t direction_index = 0;
  float position[2] = {0.f, 0.f};  // coordinates in CompactBasis(direction)
};

// The 256 fixed directions of the compact encoding: a Fibonacci lattice on
// the upper hemisphere (lines are unoriented, so a hemisphere covers all).
const std::array<Eigen::Vector3d, 256>& CompactDirections();
// Orthonormal basis (e1, e2) of the plane orthogonal to direction i.
void CompactBasis(uint8_t direction_index, Eigen::Vector3d* e1, Eigen::Vector3d* e2);
PluckerLine DecodeCompactLine(const CompactLine& compact);

// The farthest a map's line may pass from the origin, in model units (Earth-
// centred coordinates are ~6.4e6 m): beyond, products of moments overflow.
inline constexpr double kMaxLineDistance = 1e12;

struct LineCloud {
  LineEncoding encoding = LineEncoding::kPlucker;
  // Line ids: the keyed permutation of the ids of the points the lines came
  // from (lifting.h), unless keyed_line_ids is false (a version-1 file,
  // whose ids are the point ids themselves).
  std::vector<uint64_t> ids;
  bool keyed_line_ids = true;
  std::vector<PluckerLine> lines;      // always present (decoded if compact)
  std::vector<CompactLine> compact;    // the stored form when kCompact
  int descriptor_dim = 0;              // 0: no descriptors
  std::vector<uint8_t> descriptors;    // size() * descriptor_dim, row-major
  std::string descriptor_type;         // e.g. "sift-uint8"
  std::string descriptor_aggregation;  // e.g. "medoid"
  std::array<uint8_t, 16> key_fingerprint = {};
  // The map frame's gravity direction (unit), when known (lift --gravity):
  // what the +u methods align a query's gravity with. A direction, no point.
  std::optional<Eigen::Vector3d> gravity;

  size_t size() const { return ids.size(); }
  bool has_descriptors() const { return descriptor_dim > 0; }
  std::span<const uint8_t> descriptor(size_t i) const {
    return {descriptors.data() + i * descriptor_dim, static_cast<size_t>(descriptor_dim)};
  }

  // Throws Error naming `source` when sizes disagree, ids repeat, or a line
  // is not a valid Plücker line.
  void Check(std::string_view source) const;
};

}  // namespace linecloud
