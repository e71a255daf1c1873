#include "linecloud/solvers/m_p2l_lus.h"

#include <array>

#include "linecloud/solvers/m_p2p_u.h"

namespace linecloud {

int m_p2l_lus(std::span<const PluckerLine> lines,
              std::span<const Eigen::Vector3d> points_local,
              std::vector<Rigid3d>* out) {
  const std::array<Eigen::Vector3d, 2> anchors = {lines[0].Anchor(), lines[1].Anchor()};
  const std::array<Eigen::Vector3d, 2> directions = {lines[0].v, lines[1].v};
  m_p2p_u(anchors, directions, points_local, out);
  for (Rigid3d& pose : *out) pose = pose.Inverse();  // local_from_world
  return static_cast<int>(out->size());
}

}  // namespace linecloud
