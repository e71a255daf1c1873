"""Requests per second of one Localizer shared by Python threads (the GIL is
released while a request runs): client features of a fountain-P11 photo
(OpenCV's SIFT from python3-opencv) against group g00's line cloud, 1 thread
against 2, 4 and 8, each request matching on one thread.

    PYTHONPATH=build/python python3 python/bench/bench_localizer_threads.py \
        --work build/eval/fountain-P11 --photo $(bash scripts/data_dir.sh)/strecha/fountain-P11/images/0000.jpg
"""

import argparse
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np

import linecloud as lc


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", required=True, help="an eval prepare work of fountain-P11")
    parser.add_argument("--photo", required=True)
    parser.add_argument("--requests", type=int, default=32)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as keys:
        cloud = lc.lift(f"{args.work}/groups/g00/map", database=f"{args.work}/colmap/database.db",
                        key_store=keys)
    localizer = lc.Localizer(cloud, threads=1)
    camera = {"model": "PINHOLE", "width": 1536, "height": 1024,
              "params": [1379.74, 1382.08, 760.095, 503.155]}
    grey = cv2.imread(args.photo, cv2.IMREAD_GRAYSCALE)
    sift = cv2.SIFT_create(nfeatures=8192, contrastThreshold=0.02, edgeThreshold=10)
    kp, desc = lc.interop.from_opencv_sift(*sift.detectAndCompute(grey, None))
    print(f"{len(cloud)} lines, {len(kp)} client features, {args.requests} requests per row")

    def request(seed):
        start = time.perf_counter()
        r = localizer.localize_features(kp, desc, camera, seed=seed)
        assert r["success"], r.get("reason")
        return time.perf_counter() - start, r["q"]

    reference = [request(s)[1] for s in range(args.requests)]
    base = None
    print(f"{'threads':>7} {'req/s':>7} {'speed-up':>8} {'p50 ms':>7} {'p99 ms':>7}")
    for threads in (1, 2, 4, 8):
        start = time.perf_counter()
        with ThreadPoolExecutor(threads) as pool:
            results = list(pool.map(request, range(args.requests)))
        wall = time.perf_counter() - start
        assert [q for _, q in results] == reference, "results differ from one thread's"
        rate = args.requests / wall
        base = base or rate
        p50, p99 = np.percentile([t * 1e3 for t, _ in results], [50, 99])
        print(f"{threads:7d} {rate:7.1f} {rate / base:8.2f} {p50:7.1f} {p99:7.1f}")


if __name__ == "__main__":
    main()
