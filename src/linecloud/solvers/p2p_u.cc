#include "linecloud/solvers/p2p_u.h"

#include "linecloud/util/check.h"

#include <array>

#include "linecloud/solvers/m_p2p_u.h"

namespace linecloud {

int p2p_u(std::span<const Eigen::Vector3d> bearings, std::span<const Eigen::Vector3d> points,
          std::vector<Rigid3d>* out) {
  CheckMinimalSample("p2p_u", 2, out, bearings, points);
  static const std::array<Eigen::Vector3d, 2> kOrigins = {Eigen::Vector3d::Zero(),
                                                          Eigen::Vector3d::Zero()};
  return m_p2p_u(kOrigins, bearings, points, out);
}

}  // namespace linecloud
