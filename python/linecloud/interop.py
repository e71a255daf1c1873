"""Features from other extractors, in the form linecloud's maps are matched in.

linecloud's maps hold COLMAP's SIFT descriptors: RootSIFT (L1-normalised, square
root) scaled by 512 and stored as uint8, with keypoints in COLMAP's pixel
convention (the centre of the top-left pixel at (0.5, 0.5)).
"""

from __future__ import annotations

import numpy as np


def colmap_descriptors(descriptors: np.ndarray) -> np.ndarray:
    """SIFT descriptors (N x 128, any float scale, e.g. OpenCV's float32) in
    COLMAP's normalisation: L1-normalised, square-rooted, x512, uint8."""
    d = np.asarray(descriptors, dtype=np.float64)
    if d.ndim != 2 or d.shape[1] != 128:
        raise ValueError(f"descriptors: expected an N x 128 array, got shape {d.shape}")
    if not np.all(np.isfinite(d)):
        raise ValueError("descriptors: not all finite")
    l1 = np.abs(d).sum(axis=1, keepdims=True)
    root = np.sqrt(np.divide(np.abs(d), l1, out=np.zeros_like(d), where=l1 > 0))
    return np.clip(np.rint(512.0 * root), 0, 255).astype(np.uint8)


def from_opencv_sift(keypoints, descriptors: np.ndarray, *, doubled: bool = True):
    """OpenCV's SIFT (``cv2.SIFT_create().detectAndCompute``) as linecloud takes
    client features: (N x 4 keypoints x, y, scale, orientation; N x 128 uint8).

    OpenCV puts pixel centres at integers; COLMAP at +0.5. OpenCV 4.x with its
    default first octave (the image doubled) reads positions 0.25 px up and left
    of where they are, hence +0.25 when ``doubled`` (measured against VLFeat's
    keypoints: docs/fast_photo.md), else +0.5. Orientation: OpenCV's angle in
    degrees as radians; scale: OpenCV's size / 2.
    """
    shift = 0.25 if doubled else 0.5
    kp = np.array(
        [[k.pt[0] + shift, k.pt[1] + shift, 0.5 * k.size, np.deg2rad(k.angle)] for k in keypoints],
        dtype=np.float64,
    ).reshape(-1, 4)
    return kp, colmap_descriptors(descriptors)
