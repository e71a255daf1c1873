#include "linecloud/solvers/m_p3l_ls.h"

#include "linecloud/util/check.h"

#include <array>

#include "linecloud/solvers/m_p3p.h"

namespace linecloud {

int m_p3l_ls(std::span<const PluckerLine> lines, std::span<const Eigen::Vector3d> points_local,
             std::vector<Rigid3d>* out) {
  CheckMinimalSample("m_p3l_ls", 3, out, lines, points_local);
  std::array<Eigen::Vector3d, 3> anchors, directions;
  for (int i = 0; i < 3; ++i) {
    anchors[i] = lines[i].Anchor();
    directions[i] = lines[i].v;
  }
  m_p3p(anchors, directions, points_local, out,
        /*positive_depths=*/false);                  // lines have no orientation
  for (Rigid3d& pose : *out) pose = pose.Inverse();  // local_from_world
  return static_cast<int>(out->size());
}

}  // namespace linecloud
