#include "linecloud/solvers/m_p3l_ls.h"

#include <array>

#include "linecloud/solvers/m_p3p.h"

namespace linecloud {

int m_p3l_ls(std::span<const PluckerLine> lines,
             std::span<const Eigen::Vector3d> points_local, std::vector<Rigid3d>* out) {
  std::array<Eigen::Vector3d, 3> anchors, directions;
  for (int i = 0; i < 3; ++i) {
    anchors[i] = lines[i].Anchor();
    directions[i] = lines[i].v;
  }
  std::vector<Rigid3d> world_from_local;
  m_p3p(anchors, directions, points_local, &world_from_local,
        /*positive_depths=*/false);  // lines have no orientation
  out->clear();
  for (const Rigid3d& pose : world_from_local) out->push_back(pose.Inverse());
  return static_cast<int>(out->size());
}

}  // namespace linecloud
