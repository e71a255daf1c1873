// The paper's published figures the evaluation report sets beside ours —
// data, kept apart from the code that uses it.
#pragma once

#include <string_view>

namespace linecloud {

// The paper's Table 2 on its real data (Speciale et al., CVPR 2019): mean
// RANSAC iterations, inlier ratio %, mean solutions; and its mean
// reprojection errors initial / refined where it reports them (px;
// point-to-line, point-to-point against the secret points in brackets).
struct PaperRow {
  const char* method;
  double iterations, inlier_percent, solutions;
  double reprojection_initial, reprojection_refined;  // 0: not reported
};
inline constexpr PaperRow kPaper[] = {
    {"p3P", 31, 64, 2.05, 1.84, 1.42}, {"p2P+u", 15, 64, 2, 1.88, 1.43},
    {"m-p3P", 38, 64, 1.7, 0, 0},      {"m-p2P+u", 11, 65, 2, 0, 0},
    {"m-P3P+l", 23, 62, 1, 0, 0},      {"m-P2P+l+u", 12, 62, 1, 0, 0},
    {"m-P3P+l+s", 24, 62, 1, 0, 0},    {"m-P2P+l+u+s", 12, 62, 1, 0, 0},
    {"p6L", 158, 69, 64, 1.55, 1.10},  {"p4L+u", 40, 70, 4, 1.45, 1.08},
    {"m-p6L", 64, 72, 64, 0, 0},       {"m-p4L+u", 23, 72, 4, 0, 0},
    {"m-P4L+l", 27, 68, 1.5, 0, 0},    {"m-P3L+l+u", 24, 68, 1, 0, 0},
    {"m-P3L+l+s", 18, 68, 2.1, 0, 0},  {"m-P2L+l+u+s", 9, 68, 2, 0, 0}};

inline const PaperRow* PaperFor(std::string_view method) {
  for (const PaperRow& r : kPaper) {
    if (method == r.method) return &r;
  }
  return nullptr;
}

}  // namespace linecloud
