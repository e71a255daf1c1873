#pragma once

#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/plucker.h"
#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// m-P4L+l: local 3D points of unknown scale against 4 map lines — the
// generalized pose-and-scale problem with map and query swapped (Sweeney,
// Fragoso, Höllerer, Turk, "gDLS: A scalable solution to the generalized pose
// and scale problem", ECCV 2014; as posed by Speciale et al., CVPR 2019).
// Find s > 0, R, t with
//     X̃_i = s R (v_i × w_i + α_i v_i) + t,   i = 1..4.
// world_from_local puts M X̃_i + t' on line i, with M = s' R' = Q(q) the
// rotation matrix of an unnormalised quaternion q (s' = |q|²). Projected onto
// u ⟂ v_i each line gives 2 equations, linear in t' and in the 10 monomials
// q_a q_b. Seven of the eight equations are used (the last line contributes
// one): three of them (both rows of one line, one of the least parallel other
// line) give t' by Cramer's rule; substituted into the other four they leave
// G_j(q) = h_j with quadratic forms G_j; dividing out the largest h_j gives 3
// homogeneous quadrics in q, i.e. 3 quadrics in (x, y, z) for q = (1, x, y, z)
// after a fixed generic rotation of the problem (so no true pose has q_w = 0
// by construction). Their 8 intersections: with z hidden, the quadrics solved
// for (x², xy, y²) yield three relations linear in (x, y) whose determinant is
// a degree-8 polynomial in z (IntersectThreeQuadrics; a block that is
// ill-conditioned in these coordinates is retried after a fixed generic
// rotation of (x, y, z), then by a 26 × 34 elimination template,
// tools/elimination_template.py three_quadrics_z); its real roots come from
// Sturm sequences (no eigen-decomposition), (x, y) from the relations, and
// Newton steps on the quadrics polish them. Real solutions with s > 0 are
// ranked by the residual of the unused eighth equation and kept while within
// 100× of the best one (for exact data: exactly the solutions of all eight
// equations). No sign is imposed along the lines. local_from_world, best
// first.
int m_p4l_l(std::span<const PluckerLine> lines, std::span<const Eigen::Vector3d> points_local,
            std::vector<Sim3d>* out);

// The eight intersections of three quadrics in (x, y, z), each given by its
// coefficients on (1, x, y, z, x², xy, xz, y², yz, z²). Writes the real ones
// (a double root once), polished by Newton steps, and returns how many.
int IntersectThreeQuadrics(const Eigen::Matrix<double, 3, 10>& quadrics,
                           std::vector<Eigen::Vector3d>* out);

}  // namespace linecloud
