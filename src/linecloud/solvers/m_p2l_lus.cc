#include "linecloud/solvers/m_p2l_lus.h"

#include <array>

#include "linecloud/solvers/m_p2p_u.h"

namespace linecloud {

int m_p2l_lus(std::span<const PluckerLine> lines,
              std::span<const Eigen::Vector3d> points_local,
              std::vector<Rigid3d>* out) {
  const std::array<Eigen::Vector3d, 2> anchors = {lines[0].Anchor(), lines[1].Anchor()};
  const std::array<Eigen::Vector3d, 2> directions = {lines[0].v, lines[1].v};
  std::vector<Rigid3d> world_from_local;
  m_p2p_u(anchors, directions, points_local, &world_from_local);
  out->clear();
  for (const Rigid3d& pose : world_from_local) out->push_back(pose.Inverse());
  return static_cast<int>(out->size());
}

}  // namespace linecloud
