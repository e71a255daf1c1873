#pragma once

#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/plucker.h"
#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// m-p4L+u: rays of a calibrated rig against 4 map lines, known gravity (the
// problem as posed by Speciale et al., CVPR 2019, Table 1, whose solver
// follows Sweeney et al. 2015 — the upright generalized relative-pose family;
// the elimination below is our own). Find R = R_y(θ), t such that ray i (origin o_i, direction
// d_i, moment m_i = o_i × d_i, rig frame) meets the moved line
// (R v_i, R w_i + t × R v_i):
//     d_iᵀ R w_i + m_iᵀ R v_i + tᵀ (R v_i × d_i) = 0,   i = 1..4.
// With R v = c A(v) + s B(v) + D(v) each equation is row_i(c, s)·[t; 1] = 0,
// rows linear in (c, s, 1). det[row_i] = 0 with c = (1 − x²)/(1 + x²),
// s = 2x/(1 + x²) is a polynomial of degree 8 in x = tan(θ/2); t follows from
// the best-conditioned three of the four rows (Cramer's rule). Up to 8
// solutions; no sign is imposed along the lines.
int m_p4l_u(std::span<const Eigen::Vector3d> origins, std::span<const Eigen::Vector3d> directions,
            std::span<const PluckerLine> lines, std::vector<Rigid3d>* out);

// p4L+u: one camera (all rays through the origin), cam_from_world.
int p4l_u(std::span<const Eigen::Vector3d> bearings, std::span<const PluckerLine> lines,
          std::vector<Rigid3d>* out);

}  // namespace linecloud
