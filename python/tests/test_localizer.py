"""Localizer: queries, photos (path, bytes, file, array), client features,
threads — equal to the CLI's answers, and bad input raising, never crashing."""

import json
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import linecloud as lc
from conftest import fixed_key, run_cli
from geometry import centre, rotation_error_deg


def test_localize_query_equals_the_cli(demo):
    localizer = lc.Localizer(demo / "map.lcm")
    for query_path in sorted((demo / "queries").glob("*.json"))[:3]:
        query = json.loads(query_path.read_text())
        for seed in (0, 9):
            ours = localizer.localize_query(query, seed=seed)
            cli = json.loads(run_cli("localize", "--map", demo / "map.lcm", "--query", query_path,
                                     "--seed", seed, "--quiet", "--inliers"))
            assert ours["success"] == cli["success"]
            np.testing.assert_allclose(ours["q"], cli["q"], rtol=0, atol=1e-12)
            np.testing.assert_allclose(ours["t"], cli["t"], rtol=0, atol=1e-12)
            assert ours["inliers"] == cli["inliers"]
            truth = query["ground_truth"]["cam_from_world"]
            assert rotation_error_deg(ours["q"], truth["q"]) < 1.0


def test_a_rig_query_equals_the_cli(demo):
    """Three cameras of a rig as one generalized camera (m-p6L), as `localize` does it."""
    localizer = lc.Localizer(demo / "map.lcm")
    rig_path = sorted((demo / "rig_queries").glob("*.json"))[0]
    query = json.loads(rig_path.read_text())
    assert len(query["cameras"]) > 1
    ours = localizer.localize_query(query, method="m-p6L")
    cli = json.loads(run_cli("localize", "--map", demo / "map.lcm", "--query", rig_path,
                             "--method", "m-p6L", "--quiet"))
    assert ours["success"] and cli["success"]
    np.testing.assert_allclose(ours["q"], cli["q"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(ours["t"], cli["t"], rtol=0, atol=1e-12)
    truth = query["ground_truth"]
    truth = truth.get("rig_from_world", truth.get("cam_from_world"))
    assert rotation_error_deg(ours["q"], truth["q"]) < 1.0


def test_result_dict_has_the_documented_keys(demo):
    query = json.loads(sorted((demo / "queries").glob("*.json"))[0].read_text())
    r = lc.Localizer(demo / "map.lcm").localize_query(query)
    for key in ("success", "q", "t", "center", "num_inliers", "inlier_ratio", "inliers",
                "uncertainty", "times_ms"):
        assert key in r, key
    np.testing.assert_allclose(r["center"], centre(r), atol=1e-9)
    assert "inliers" not in lc.Localizer(demo / "map.lcm").localize_query(query, with_inliers=False)


def test_a_query_that_cannot_be_localized_is_a_result(demo):
    query = json.loads(sorted((demo / "queries").glob("*.json"))[0].read_text())
    query["observations"] = query["observations"][:8]
    r = lc.Localizer(demo / "map.lcm").localize_query(query, method="p6L")
    assert r["success"] is False and r["reason"]


def test_bad_queries_and_options_raise(demo):
    localizer = lc.Localizer(demo / "map.lcm")
    query = json.loads(sorted((demo / "queries").glob("*.json"))[0].read_text())
    with pytest.raises(ValueError, match=r"observations\[0\]"):
        localizer.localize_query(dict(query, observations=[{"camera": 0}] + query["observations"]))
    with pytest.raises(ValueError, match="unknown method"):
        localizer.localize_query(query, method="p7L")
    with pytest.raises(TypeError, match="unexpected keyword argument 'thresold'"):
        localizer.localize_query(query, thresold=3)
    with pytest.raises(TypeError, match="QUERY.json-like dict"):
        localizer.localize_query([query])
    with pytest.raises(ValueError, match=r"threads must be a whole number in \[1, 1024\]"):
        lc.Localizer(demo / "map.lcm", threads=0)
    with pytest.raises(ValueError, match="features must be one of colmap, opencv, got \"sift\""):
        lc.Localizer(demo / "map.lcm", features="sift")
    with pytest.raises(FileNotFoundError):
        lc.Localizer(demo / "missing.lcm")
    # The demo map has no descriptors: photos are refused with the reason.
    with pytest.raises(ValueError, match="descriptor"):
        localizer.localize_features(np.zeros((10, 2)), np.zeros((10, 128), np.uint8),
                                    query["cameras"][0])


@pytest.fixture(scope="module")
def fountain_localizer(fountain, tmp_path_factory):
    folder = tmp_path_factory.mktemp("fountain-keys")
    cloud = lc.lift(fountain["model"], database=fountain["database"], key_file=fixed_key(folder),
                    key_store=folder / "keys")
    return cloud, lc.Localizer(cloud, threads=1)


def _near_truth(r, truth):
    assert r["success"], r.get("reason")
    assert rotation_error_deg(r["q"], truth["q"]) < 0.5
    assert np.linalg.norm(centre(r) - centre(truth)) < 0.05


def test_a_photo_by_path_bytes_file_and_array(fountain, fountain_localizer):
    cloud, localizer = fountain_localizer
    cv2 = pytest.importorskip("cv2", reason="python3-opencv reads the photo into an array")
    camera = fountain["camera"]
    by_path = localizer.localize_image(fountain["photo"], camera)
    _near_truth(by_path, fountain["truth"])
    data = fountain["photo"].read_bytes()
    assert localizer.localize_image(data, camera)["q"] == by_path["q"]
    assert localizer.localize_image(memoryview(data), camera)["q"] == by_path["q"]
    with open(fountain["photo"], "rb") as f:
        assert localizer.localize_image(f, camera)["q"] == by_path["q"]
    grey = cv2.imread(str(fountain["photo"]), cv2.IMREAD_GRAYSCALE)
    _near_truth(localizer.localize_image(grey, camera), fountain["truth"])


def test_a_camera_as_the_clis_string_or_a_pycolmap_camera(fountain, fountain_localizer):
    """[newcomer] The camera as the CLI, the service and the console take it, and as pycolmap
    holds it (an object with model — an enum with a name —, width, height, params)."""
    import types
    import enum
    cloud, localizer = fountain_localizer
    camera = fountain["camera"]
    by_dict = localizer.localize_image(fountain["photo"], camera)
    text = " ".join([camera["model"], str(camera["width"]), str(camera["height"]),
                     *map(repr, camera["params"])])
    assert localizer.localize_image(fountain["photo"], text)["q"] == by_dict["q"]
    model = enum.Enum("CameraModelId", {camera["model"]: 1})[camera["model"]]
    like_pycolmap = types.SimpleNamespace(model=model, width=camera["width"],
                                          height=camera["height"],
                                          params=np.array(camera["params"]))
    assert localizer.localize_image(fountain["photo"], like_pycolmap)["q"] == by_dict["q"]
    with pytest.raises(ValueError, match="drop the id"):
        localizer.localize_image(fountain["photo"], "1 " + text)


def test_equal_to_the_cli_on_a_photo(fountain, fountain_localizer, tmp_path):
    cloud, localizer = fountain_localizer
    cloud.write(tmp_path / "fountain.lcm")
    camera = fountain["camera"]
    cli = json.loads(run_cli("localize", "--map", tmp_path / "fountain.lcm", "--image",
                             fountain["photo"], "--camera",
                             "PINHOLE 1536 1024 " + " ".join(map(str, camera["params"])),
                             "--quiet"))
    ours = localizer.localize_image(fountain["photo"], camera)
    np.testing.assert_allclose(ours["q"], cli["q"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(ours["t"], cli["t"], rtol=0, atol=1e-12)
    assert ours["num_matches"] == cli["num_matches"]


def test_opencv_sift_from_python_localizes(fountain, fountain_localizer):
    cv2 = pytest.importorskip("cv2", reason="python3-opencv gives the other extractor")
    _, localizer = fountain_localizer
    grey = cv2.imread(str(fountain["photo"]), cv2.IMREAD_GRAYSCALE)
    sift = cv2.SIFT_create(nfeatures=8192, contrastThreshold=0.02, edgeThreshold=10)
    keypoints, descriptors = sift.detectAndCompute(grey, None)
    kp, desc = lc.interop.from_opencv_sift(keypoints, descriptors)
    assert desc.dtype == np.uint8 and kp.shape == (len(keypoints), 4)
    r = localizer.localize_features(kp, desc, fountain["camera"])
    _near_truth(r, fountain["truth"])
    # Positions only (N x 2) localize too.
    _near_truth(localizer.localize_features(kp[:, :2], desc, fountain["camera"]), fountain["truth"])
    # [newcomer] One photo's keypoints as a Python list of [x, y] (not a rig of photos).
    listed = localizer.localize_features(kp[:, :2].tolist(), desc, fountain["camera"])
    assert listed["q"] == localizer.localize_features(kp[:, :2], desc, fountain["camera"])["q"]
    # [newcomer] OpenCV's descriptors not converted: as floats a TypeError naming the converter;
    # cast to bytes (L2-normalised, not RootSIFT: 146 inliers where 479) a ValueError saying so.
    with pytest.raises(TypeError, match="from_opencv_sift"):
        localizer.localize_features(kp, descriptors, fountain["camera"])
    with pytest.raises(ValueError, match="look like L2-normalised SIFT"):
        localizer.localize_features(kp, descriptors.astype(np.uint8), fountain["camera"])


def test_bad_photos_raise(fountain, fountain_localizer, tmp_path):
    _, localizer = fountain_localizer
    camera = fountain["camera"]
    with pytest.raises(ValueError):
        localizer.localize_image(b"not an image", camera)
    f = open(fountain["photo"], "rb")
    f.close()
    with pytest.raises(ValueError, match="closed file"):
        localizer.localize_image(f, camera)
    with pytest.raises(FileNotFoundError):
        localizer.localize_image(tmp_path / "missing.jpg", camera)
    with pytest.raises(TypeError, match="grey uint8"):
        localizer.localize_image(np.zeros((1024, 1536, 3), np.uint8), camera)
    with pytest.raises(TypeError, match="grey uint8"):
        localizer.localize_image(np.zeros((1024, 1536), np.float32), camera)
    with pytest.raises(ValueError, match="the image is 100x100 pixels but the camera is 1536x1024"):
        localizer.localize_image(np.zeros((100, 100), np.uint8), camera)
    with pytest.raises(ValueError, match="descriptors: expected an N x 128 array"):
        localizer.localize_features(np.zeros((5, 2)), np.zeros((5, 64), np.uint8), camera)
    with pytest.raises(ValueError, match="5 keypoints but 4 descriptors"):
        localizer.localize_features(np.zeros((5, 2)), np.zeros((4, 128), np.uint8), camera)
    nan = np.zeros((5, 2))
    nan[2, 0] = np.nan
    with pytest.raises(ValueError, match=r"keypoints\[2, 0\]: not a finite number"):
        localizer.localize_features(nan, np.zeros((5, 128), np.uint8), camera)
    with pytest.raises(ValueError, match="2 photos need 2 cam_from_rig poses"):
        localizer.localize_image([fountain["photo"]] * 2, camera, method="m-p6L")
    # A 138-byte PNG announcing 60000 x 60000 pixels: refused from its header.
    import struct
    import zlib
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    bomb = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 60000, 60000, 8, 0, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b""))
    start = time.monotonic()
    with pytest.raises(ValueError, match="pixels"):
        localizer.localize_image(bomb, dict(camera, width=60000, height=60000))
    assert time.monotonic() - start < 1.0


def test_eight_python_threads_share_one_localizer(fountain, fountain_localizer):
    """The GIL is released in every request: eight threads on one Localizer run
    in parallel (process CPU time over wall time above 1 on a multi-core
    machine) and answer exactly what one thread answers."""
    cv2 = pytest.importorskip("cv2", reason="python3-opencv gives client features")
    _, localizer = fountain_localizer
    grey = cv2.imread(str(fountain["photo"]), cv2.IMREAD_GRAYSCALE)
    sift = cv2.SIFT_create(nfeatures=8192, contrastThreshold=0.02, edgeThreshold=10)
    kp, desc = lc.interop.from_opencv_sift(*sift.detectAndCompute(grey, None))
    seeds = list(range(16))

    def work(seed):
        return localizer.localize_features(kp, desc, fountain["camera"], seed=seed)

    one = [work(s) for s in seeds]
    cpu, wall = time.process_time(), time.perf_counter()
    with ThreadPoolExecutor(8) as pool:
        many = list(pool.map(work, seeds))
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    for a, b in zip(one, many):
        assert a["q"] == b["q"] and a["t"] == b["t"] and a["inliers"] == b["inliers"]
    # While the GIL is released a pure-Python thread keeps running.
    ticks = [0]
    done = threading.Event()

    def count():
        while not done.is_set():
            ticks[0] += 1

    counter = threading.Thread(target=count)
    counter.start()
    work(0)
    done.set()
    counter.join()
    assert ticks[0] > 1000
    import os
    if (os.cpu_count() or 1) >= 2:
        assert cpu / wall > 1.3, f"CPU {cpu:.2f} s over wall {wall:.2f} s: no parallelism"


def test_a_process_bounds_its_photos_memory(fountain, fountain_localizer):
    """[newcomer] What a thread localizing photos holds (photo_memory_mb) and a bound for the
    process (set_memory_limit, as serve's --memory-budget-mb): never more reserved at once,
    a photo that alone needs more is a ValueError naming both."""
    cloud, localizer = fountain_localizer
    need = lc.photo_memory_mb(1536, 1024)
    assert 400 < need < 700, need  # ~320 bytes per pixel
    for bad in (-1, 1e-7, float("nan"), 1e8):  # (a tiny limit was 0 bytes: none)
        with pytest.raises(ValueError, match=r"mb must be 0 \(no limit\) or a number in \[1, 1e7\]"):
            lc.set_memory_limit(bad)
    try:
        lc.set_memory_limit(100)
        with pytest.raises(ValueError, match=rf"needs {int(need)} MB of scale space, more than the memory limit of 100 MB"):
            localizer.localize_image(fountain["photo"], fountain["camera"])
        # Room for one photo at a time: three threads take turns, every one localized.
        lc.set_memory_limit(need * 1.5)
        assert lc.memory_in_use()["limit_mb"] == pytest.approx(need * 1.5, abs=1)
        peak, done = [0.0], threading.Event()

        def watch():
            while not done.is_set():
                peak[0] = max(peak[0], lc.memory_in_use()["reserved_mb"])
                time.sleep(0.002)

        watcher = threading.Thread(target=watch)
        watcher.start()
        try:
            with ThreadPoolExecutor(3) as pool:
                results = list(pool.map(lambda _: localizer.localize_image(fountain["photo"], fountain["camera"]),
                                        range(3)))
        finally:
            done.set()
            watcher.join()
        assert all(r["success"] for r in results)
        assert need * 0.9 <= peak[0] <= need * 1.5, peak[0]
        # The limit lowered below a photo's need while it waits for room: a ValueError once
        # the room is there, not a wait for ever (an outsider's photo never returned).
        lc.set_memory_limit(need * 1.2)
        first = threading.Thread(target=lambda: localizer.localize_image(fountain["photo"], fountain["camera"]))
        first.start()
        time.sleep(0.2)
        threading.Timer(0.2, lambda: lc.set_memory_limit(100)).start()
        started = time.monotonic()
        with pytest.raises(ValueError, match=r"more than the memory limit of 100 MB"):
            localizer.localize_image(fountain["photo"], fountain["camera"])
        first.join(30)
        assert not first.is_alive() and time.monotonic() - started < 30
    finally:
        lc.set_memory_limit(0)
    assert lc.memory_in_use()["limit_mb"] == 0
