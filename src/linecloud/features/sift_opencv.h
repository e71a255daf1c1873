// SIFT by OpenCV 4.6 (Debian's libopencv-features2d: SIMD kernels, threads
// through OpenCV's pool): Lowe's detector and descriptor (D. G. Lowe,
// "Distinctive Image Features from Scale-Invariant Keypoints", IJCV 2004)
// with COLMAP's options carried over, so that its features match maps built
// by COLMAP:
//   - contrast threshold = COLMAP's peak threshold x levels per octave (OpenCV
//     divides by the levels, VLFeat does not), edge threshold 10, sigma 1.6,
//     the image doubled first (first octave -1);
//   - only COLMAP's octaves (first_octave .. first_octave + num_octaves - 1;
//     OpenCV would go on to the coarsest), and COLMAP's cap: the finest DoG
//     levels dropped until at most max_num_features detections remain, the
//     level crossing it kept whole (OpenCV would keep the strongest responses);
//   - keypoints moved to COLMAP's pixel convention (+0.5, less the 0.25 px
//     OpenCV's doubling shifts them by), scale = sigma,
//     orientation in radians in image axes (y down) as VLFeat's;
//   - OpenCV's descriptor is in UBC bin order already: L1-root, x 512, bytes
//     (RootSiftBytes).
// The order of the features is fixed (response, then position), whatever the
// thread count.
#pragma once

#include "linecloud/features/sift.h"

namespace linecloud {

SiftFeatures ExtractSiftOpenCV(const GreyImage& image, const SiftOptions& options = {});

// OpenCV's thread count for extraction (1: the calling thread only). It is
// process-wide: set it once before extracting (e.g. from --threads), not while
// other threads extract.
void SetOpenCVThreads(int threads);
int OpenCVThreads();

}  // namespace linecloud
