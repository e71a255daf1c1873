"""Overhead of the binding: estimate_pose from Python against the same C++ call.

For each method, the same seeded instances (real-ish sizes and inlier ratios)
are localized (a) from Python through lc.estimate_pose, numpy in and dicts out,
and (b) in C++ on the instance prepared once (lc._core._time_estimate_pose,
no Python in the loop). Reports p50 / p99 per call and the ratio of medians.

    PYTHONPATH=build/python python3 python/bench/bench_estimate_pose.py [--calls 200]
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import linecloud as lc  # noqa: E402
from geometry import lines_through, separate_line_outliers, synthetic_instance  # noqa: E402


def instance(method, n, outliers, seed):
    rng = np.random.default_rng(seed)
    camera, truth, xy, points, inlier = synthetic_instance(rng, n=n, outliers=outliers, noise_px=0.5)
    if method == "p6L":
        world = lines_through(points, rng)
        xy = separate_line_outliers(rng, world, truth, xy, inlier)
        return camera, xy, world
    return camera, xy, points


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=100, help="calls per method and side")
    parser.add_argument("--correspondences", type=int, default=1000)
    parser.add_argument("--outliers", type=float, default=0.3)
    args = parser.parse_args()
    print(f"{args.calls} calls per side, {args.correspondences} correspondences, "
          f"{args.outliers:.0%} outliers, one thread")
    print(f"{'method':8} {'python p50 ms':>14} {'p99':>8} {'C++ p50 ms':>11} {'p99':>8} {'ratio':>6}")
    for method in ("p3P", "p6L"):
        camera, xy, world = instance(method, args.correspondences, args.outliers, seed=1)
        options = {"ransac": {"seed": 0}}
        py_times = []
        for _ in range(args.calls):
            start = time.perf_counter()
            pose, info = lc.estimate_pose(method, xy, world, camera, **options)
            py_times.append(time.perf_counter() - start)
            assert info["success"], info.get("reason")
        cpp_times = lc._core._time_estimate_pose(args.calls, method, xy, world, camera, **options)
        p = np.percentile(np.array(py_times) * 1e3, [50, 99])
        c = np.percentile(np.array(cpp_times) * 1e3, [50, 99])
        print(f"{method:8} {p[0]:14.3f} {p[1]:8.3f} {c[0]:11.3f} {c[1]:8.3f} {p[0] / c[0]:6.3f}")


if __name__ == "__main__":
    main()
