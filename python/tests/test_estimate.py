"""estimate_pose, solve and methods: poses to the truth, inliers, bad input."""

import numpy as np
import pytest

import linecloud as lc
from geometry import (lines_through, quat_to_matrix, random_rotation, rotation_error_deg,
                      separate_line_outliers, synthetic_instance)


def test_methods_are_the_papers_sixteen():
    methods = lc.methods()
    assert len(methods) == 16
    names = [m["name"] for m in methods]
    assert names[0] == "p3P" and "p6L" in names and "m-P2L+l+u+s" in names
    assert all(m["implemented"] for m in methods)


@pytest.mark.parametrize("method", ["p3P", "p6L"])
def test_estimate_pose_finds_the_true_pose_and_its_inliers(method):
    rng = np.random.default_rng(7)
    camera, truth, xy, points, inlier = synthetic_instance(rng, n=300, outliers=0.4)
    world = lines_through(points, rng) if method == "p6L" else points
    if method == "p6L":
        xy = separate_line_outliers(rng, world, truth, xy, inlier)
    pose, info = lc.estimate_pose(method, xy, world, camera, ransac={"seed": 3})
    assert info["success"], info.get("reason")
    # PoseLib's convention: the pose is the package's pose type (lc.Pose), q with w >= 0.
    assert isinstance(pose, lc.Pose) and pose.q[0] >= 0
    np.testing.assert_allclose(pose.center, -pose.R.T @ pose.t)
    assert rotation_error_deg(pose["q"], truth["q"]) < 1e-6
    np.testing.assert_allclose(pose["t"], truth["t"], atol=1e-7)
    mask = info["inliers"]
    assert mask.dtype == bool and mask.shape == (300,)
    assert np.array_equal(mask, inlier)
    assert info["num_inliers"] == mask.sum()
    # The Localizer's convention beside PoseLib's: the same inliers as indices.
    np.testing.assert_array_equal(info["inlier_indices"], np.flatnonzero(mask))


def test_same_seed_same_pose_and_a_generalized_camera():
    rng = np.random.default_rng(11)
    cams, xys, worlds, truths = [], [], [], []
    # A rig of two cameras: the second 0.3 units to the right of the first.
    camera, truth, xy, points, _ = synthetic_instance(rng, n=150, outliers=0.3)
    rig_from_world = truth
    offset = np.array([-0.3, 0.0, 0.0])
    cam_from_rig = [{"q": [1, 0, 0, 0], "t": [0, 0, 0]}, {"q": [1, 0, 0, 0], "t": list(offset)}]
    R = quat_to_matrix(rig_from_world["q"])
    for c in range(2):
        # Points seen by camera c: project with cam_from_world = cam_from_rig ∘ rig_from_world.
        x_rig = points @ R.T + rig_from_world["t"]
        x_cam = x_rig + (offset if c == 1 else 0)
        ahead = x_cam[:, 2] > 0.1
        uv = np.column_stack([800 * x_cam[:, 0] / x_cam[:, 2] + 500, 800 * x_cam[:, 1] / x_cam[:, 2] + 400])
        cams.append(camera)
        xys.append(uv[ahead])
        worlds.append(lines_through(points[ahead], rng))
    pose_a, info_a = lc.estimate_pose("m-p6L", xys, worlds, cams, cam_from_rig=cam_from_rig,
                                      ransac={"seed": 5})
    pose_b, _ = lc.estimate_pose("m-p6L", xys, worlds, cams, cam_from_rig=cam_from_rig,
                                 ransac={"seed": 5})
    assert info_a["success"], info_a.get("reason")
    assert pose_a == pose_b
    assert rotation_error_deg(pose_a["q"], rig_from_world["q"]) < 1e-6
    np.testing.assert_allclose(pose_a["t"], rig_from_world["t"], atol=1e-7)


def test_non_contiguous_and_integer_arrays_give_the_same_pose():
    rng = np.random.default_rng(3)
    camera, truth, xy, points, _ = synthetic_instance(rng, n=120, outliers=0.2)
    pose, _ = lc.estimate_pose("p3P", xy, points, camera, ransac={"seed": 1})
    fortran_xy = np.asfortranarray(xy)
    strided = np.zeros((120, 6))
    strided[:, ::2] = points
    pose_f, _ = lc.estimate_pose("p3P", fortran_xy, strided[:, ::2], camera, ransac={"seed": 1})
    assert pose == pose_f
    pose_32, info = lc.estimate_pose("p3P", xy.astype(np.float32), points, camera, ransac={"seed": 1})
    assert info["success"] and rotation_error_deg(pose_32["q"], truth["q"]) < 1e-3


def test_too_few_inliers_is_a_result_not_an_exception():
    rng = np.random.default_rng(5)
    camera, _, xy, points, _ = synthetic_instance(rng, n=25, outliers=0.0)
    pose, info = lc.estimate_pose("p3P", xy, points, camera)  # 25 < COLMAP's 30 inliers
    assert not info["success"] and "inliers" in info["reason"] and pose is not None
    pose, info = lc.estimate_pose("p3P", xy, points, camera, success=False)
    assert info["success"] and pose is not None


def _instance():
    rng = np.random.default_rng(1)
    return synthetic_instance(rng, n=50)


@pytest.mark.parametrize("points2d, points3d, error, text", [
    (np.zeros((50, 3)), None, ValueError, "points2D: expected an N x 2 array, got shape (50, 3)"),
    (np.array([["a", "b"]] * 50), None, TypeError, "points2D: expected a float or integer array"),
    ("nan", None, ValueError, "points2D[7, 1]: not a finite number (nan)"),
    (None, np.zeros((49, 3)), ValueError, "50 2D points but 49 points3D"),
    ([np.zeros((50, 2))], None, ValueError, "p3P takes one camera"),
    (None, np.zeros((50, 6)), ValueError, "points3D: expected an N x 3 array"),
])
def test_bad_arrays_raise_naming_the_argument(points2d, points3d, error, text):
    camera, _, xy, points, _ = _instance()
    if isinstance(points2d, str):
        points2d = xy.copy()
        points2d[7, 1] = np.nan
    with pytest.raises(error) as e:
        lc.estimate_pose("p3P", xy if points2d is None else points2d,
                         points if points3d is None else points3d, camera)
    assert text in str(e.value)


def test_bad_options_and_cameras_raise():
    camera, _, xy, points, _ = _instance()
    with pytest.raises(ValueError, match="unknown method 'p5P'"):
        lc.estimate_pose("p5P", xy, points, camera)
    with pytest.raises(TypeError, match="unknown option 'max_err'"):
        lc.estimate_pose("p3P", xy, points, camera, ransac={"max_err": 2})
    with pytest.raises(ValueError, match="RANSAC threshold must be a positive number"):
        lc.estimate_pose("p3P", xy, points, camera, ransac={"max_error": -1})
    with pytest.raises(ValueError, match="camera.model: unknown camera model 'PINHOLES'"):
        lc.estimate_pose("p3P", xy, points, dict(camera, model="PINHOLES"))
    with pytest.raises(ValueError, match="camera: field 'params' is missing"):
        lc.estimate_pose("p3P", xy, points, {"model": "PINHOLE", "width": 1, "height": 1})
    with pytest.raises(TypeError, match="expected a camera dict"):
        lc.estimate_pose("p3P", xy, points, [800, 800, 500, 400])


def test_solve_returns_the_true_pose_among_its_solutions():
    rng = np.random.default_rng(21)
    q, t = random_rotation(rng), rng.normal(size=3)
    R = quat_to_matrix(q)
    points = rng.normal(size=(6, 3)) + [0, 0, 6]
    points = (points - t) @ R  # world points whose camera-frame coordinates are ~6 ahead
    x_cam = points @ R.T + t
    bearings = x_cam / np.linalg.norm(x_cam, axis=1, keepdims=True)
    for method, sample in [("p3P", {"bearings": bearings[:3], "points": points[:3]}),
                           ("p6L", {"bearings": bearings, "lines": lines_through(points, rng)})]:
        solutions = lc.solve(method, **sample)
        assert solutions, method
        best = min(solutions, key=lambda s: rotation_error_deg(s["q"], q) + np.linalg.norm(np.subtract(s["t"], t)))
        assert rotation_error_deg(best["q"], q) < 1e-6, method
        np.testing.assert_allclose(best["t"], t, atol=1e-8)
        assert "scale" not in best
    # Sim3 (+l methods without +s, the known scale): the scale comes back.
    scale = 2.5
    local = (x_cam[:3]) / scale
    sim = lc.solve("m-P3P+l", bearings=bearings[:3], camera_index=[0, 0, 0],
                   cam_from_rig=[{"q": [1, 0, 0, 0], "t": [0, 0, 0]}], points_local=local,
                   points=points[:3])
    assert any(abs(s["scale"] - 1 / scale) < 1e-8 or abs(s["scale"] - scale) < 1e-8 for s in sim)


def test_solve_rejects_a_wrong_sample():
    with pytest.raises(ValueError, match="bearings"):
        lc.solve("p3P", bearings=np.ones((2, 3)), points=np.ones((3, 3)))
    with pytest.raises(TypeError, match="unknown option 'point'"):
        lc.solve("p3P", point=np.ones((3, 3)))


def test_lines_in_a_wrong_layout_are_refused_naming_the_line():
    """[X, v] instead of [v, w = X x v]: refused before RANSAC, not a misleading no-pose."""
    rng = np.random.default_rng(8)
    camera, truth, xy, points, _ = synthetic_instance(rng, n=60, outliers=0.0)
    lines = lines_through(points, rng)
    wrong = np.hstack([points, lines[:, :3]])  # a point and a direction
    with pytest.raises(ValueError, match=r"lines\[0\] is not a Pluecker line \[v, w\]"):
        lc.estimate_pose("p6L", xy, wrong, camera)
    zero = lines.copy()
    zero[5, :3] = 0
    with pytest.raises(ValueError, match=r"lines\[5\]: the direction v is zero"):
        lc.estimate_pose("p6L", xy, zero, camera)
    # Any length of v is the same line: the same pose.
    scaled = lines * rng.uniform(0.5, 3, size=(60, 1))
    a, _ = lc.estimate_pose("p6L", xy, lines, camera, ransac={"seed": 1})
    b, _ = lc.estimate_pose("p6L", xy, scaled, camera, ransac={"seed": 1})
    np.testing.assert_allclose(a["q"], b["q"], atol=1e-9)
    np.testing.assert_allclose(a["t"], b["t"], atol=1e-9)


def test_ctrl_c_stops_a_long_estimate_pose():
    """estimate_pose polls Python's signal handlers while RANSAC runs without the GIL: Ctrl-C
    ends a run of 10^8 iterations (it was ignored: an outsider's run went on for 14 min)."""
    import signal
    import threading
    import time
    rng = np.random.default_rng(1)
    points = rng.uniform(-1, 1, (100, 3)) + [0, 0, 5]
    v = rng.normal(size=(100, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    camera = {"model": "PINHOLE", "width": 1000, "height": 1000, "params": [500, 500, 500, 500]}
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(0.5, lambda: signal.raise_signal(signal.SIGINT))
    start = time.monotonic()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            lc.estimate_pose("p6L", rng.uniform(0, 1000, (100, 2)),
                             np.hstack([v, np.cross(points, v)]), camera,
                             ransac={"min_iterations": 10**8, "max_iterations": 10**8,
                                     "max_seconds": 30})
    finally:
        signal.signal(signal.SIGINT, previous)
    timer.join()
    assert 0.5 <= time.monotonic() - start < 3
