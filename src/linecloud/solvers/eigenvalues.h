// Eigenvalues (no vectors) of a small dense real matrix, for the action-matrix
// solvers: Hessenberg reduction by stabilised elementary similarity transforms
// (Gaussian elimination with partial pivoting, ~5n³/6 flops instead of the
// 10n³/3 of Householder), then the Francis implicit double-shift QR iteration
// updating only the active window, since no Schur vectors or triangular factor
// are wanted (Golub & Van Loan, Matrix Computations, 4th ed., Alg. 7.4.2 and
// 7.5.1/7.5.2 with "wantT = false").
#pragma once

#include <complex>
#include <vector>

#include <Eigen/Core>

namespace linecloud {

// All n eigenvalues of the square matrix `a` (n ≤ 128; overwritten). Returns false when
// the QR iteration does not converge within 60 sweeps per eigenvalue or the
// input is not finite; `values` then holds what was found.
bool EigenvaluesInPlace(Eigen::MatrixXd* a, std::vector<std::complex<double>>* values);

}  // namespace linecloud
