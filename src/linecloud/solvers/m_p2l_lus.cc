#include "linecloud/solvers/m_p2l_lus.h"

#include "linecloud/util/check.h"

#include <array>

#include "linecloud/solvers/m_p2p_u.h"
#include "linecloud/solvers/upright.h"

namespace linecloud {

int m_p2l_lus(std::span<const PluckerLine> lines, std::span<const Eigen::Vector3d> points_local,
              std::vector<Rigid3d>* out) {
  CheckMinimalSample("m_p2l_lus", 2, out, lines, points_local);
  const std::array<Eigen::Vector3d, 2> anchors = {lines[0].Anchor(), lines[1].Anchor()};
  const std::array<Eigen::Vector3d, 2> directions = {lines[0].v, lines[1].v};
  out->clear();
  UprightSolution solutions[2];
  const int count = m_p2p_u(anchors, directions, points_local, solutions);
  for (int k = 0; k < count; ++k) {
    // local_from_world = (R_y(θ)ᵀ, −R_y(θ)ᵀ t), R_y(θ)ᵀ = R_y(−θ).
    const double c = solutions[k].c, s = solutions[k].s;
    const Eigen::Vector3d& t = solutions[k].t;
    out->emplace_back(upright::RotationYUnit(c, -s),
                      Eigen::Vector3d(s * t.z() - c * t.x(), -t.y(), -s * t.x() - c * t.z()));
  }
  return count;
}

}  // namespace linecloud
