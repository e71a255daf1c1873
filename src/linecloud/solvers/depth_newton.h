// The Newton step shared by the three-point solvers (p3P, m-p3P) on their
// pairwise distance equations r01(λ0, λ1), r02(λ0, λ2), r12(λ1, λ2) = 0: each
// equation misses one depth, so the Jacobian has a zero in every row,
//     J = [j00 j01 0; j10 0 j12; 0 j21 j22],
// and J s = r is solved by Cramer's rule in scalars (Eigen temporaries filled
// entry by entry and read back at once stall on store forwarding here).
#pragma once

#include <cmath>

namespace linecloud {

// s = J⁻¹ r; false when J is singular or the step is not finite.
inline bool SolvePairwiseJacobian(double j00, double j01, double j10, double j12, double j21,
                                  double j22, double r0, double r1, double r2, double* s0,
                                  double* s1, double* s2) {
  const double inv_det = -1 / (j00 * j12 * j21 + j01 * j10 * j22);
  const double m = r1 * j22 - j12 * r2;
  *s0 = (-r0 * j12 * j21 - j01 * m) * inv_det;
  *s1 = (j00 * m - r0 * j10 * j22) * inv_det;
  *s2 = (r0 * j10 * j21 - j00 * r1 * j21 - j01 * j10 * r2) * inv_det;
  return std::isfinite(*s0 + *s1 + *s2);
}

}  // namespace linecloud
