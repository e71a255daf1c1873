"""lc.Pose: one type for a pose (cam_from_world, q = (w, x, y, z)), read from and written to the
dicts results and JSON use, and taken wherever a pose dict is."""

import json

import numpy as np
import pytest

import linecloud as lc


def _random_pose(rng, scale=1.0):
    q = rng.normal(size=4)
    return lc.Pose(q, rng.normal(size=3) * 3, scale)


def test_matrix_inverse_and_composition_agree():
    rng = np.random.default_rng(5)
    for scale in (1.0, 0.37, 4.2):
        a, b = _random_pose(rng, scale), _random_pose(rng)
        assert a.q[0] >= 0 and abs(np.linalg.norm(a.q) - 1) < 1e-15
        np.testing.assert_allclose(a.R @ a.R.T, np.eye(3), atol=1e-14)
        assert abs(np.linalg.det(a.R) - 1) < 1e-14
        back = lc.Pose.from_matrix(a.matrix)
        np.testing.assert_allclose(back.q, a.q, atol=1e-14)
        np.testing.assert_allclose(back.t, a.t, atol=1e-13)
        assert abs(back.scale - a.scale) < 1e-13
        x = rng.normal(size=(5, 3))
        np.testing.assert_allclose(a.inverse().transform(a.transform(x)), x, atol=1e-12)
        np.testing.assert_allclose((a @ b).transform(x), a.transform(b.transform(x)), atol=1e-12)
        np.testing.assert_allclose(a.transform(a.center[None]), [[0, 0, 0]], atol=1e-12)
        d = a.to_dict()
        json.dumps(d)  # serialisable as it is
        assert ("scale" in d) == (scale != 1.0)
        np.testing.assert_allclose(lc.Pose.from_dict(d).matrix, a.matrix, atol=0)
        # [newcomer] The 4x4 form, and a rigid matrix read back as rigid (no "scale": 0.999...).
        assert a.matrix4.shape == (4, 4)
        np.testing.assert_array_equal(a.matrix4[:3], a.matrix)
        np.testing.assert_array_equal(a.matrix4[3], [0, 0, 0, 1])
        back4 = lc.Pose.from_matrix(a.matrix4)
        assert ("scale" in back4.to_dict()) == (scale != 1.0)


def test_bad_poses_are_refused():
    with pytest.raises(ValueError, match="q must be"):
        lc.Pose([0, 0, 0, 0], [0, 0, 0])
    with pytest.raises(ValueError, match="t must be"):
        lc.Pose([1, 0, 0, 0], [0, 0])
    with pytest.raises(ValueError, match="scale must be"):
        lc.Pose([1, 0, 0, 0], [0, 0, 0], -1)
    with pytest.raises(ValueError, match="check its 'success'"):
        lc.Pose.from_dict({"success": False, "reason": "no"})


def test_a_result_reads_as_a_pose_and_a_pose_is_taken_as_cam_from_rig(demo):
    query = json.loads(sorted((demo / "rig_queries").glob("*.json"))[0].read_text())
    localizer = lc.Localizer(demo / "map.lcm")
    r = localizer.localize_query(query)
    assert r["success"], r.get("reason")
    pose = lc.Pose.from_dict(r)
    np.testing.assert_allclose(pose.center, r["center"], atol=1e-9)
    # A Pose where a pose dict goes: a rig's cam_from_rig.
    first = query["cameras"][0] if "cameras" in query else None
    assert first is not None
    f = lc.Pose.from_dict({"q": [1, 0, 0, 0], "t": [0.1, 0, 0]})
    keypoints = np.zeros((6, 2))
    with pytest.raises(ValueError, match="descriptor"):  # the demo map has no descriptors
        localizer.localize_features([keypoints, keypoints],
                                    [np.zeros((6, 128), np.uint8)] * 2, [first, first],
                                    method="m-p6L", cam_from_rig=[lc.Pose(), f])
    with pytest.raises(TypeError, match="cam_from_rig"):
        localizer.localize_features([keypoints, keypoints],
                                    [np.zeros((6, 128), np.uint8)] * 2, [first, first],
                                    method="m-p6L", cam_from_rig=[lc.Pose(), 3])


def test_from_pycolmap_and_read_as_a_dict():
    """[newcomer] pycolmap's Rigid3d keeps its quaternion as (x, y, z, w); estimate_pose and
    solve return a Pose that still reads as the dicts they returned before."""
    from types import SimpleNamespace
    pose = lc.Pose([0.5, 0.5, -0.5, 0.5], [1.0, 2.0, 3.0])
    rigid = SimpleNamespace(rotation=SimpleNamespace(quat=np.array([0.5, -0.5, 0.5, 0.5])),
                            translation=np.array([1.0, 2.0, 3.0]))
    assert lc.Pose.from_pycolmap(rigid) == pose
    assert pose["q"] == [0.5, 0.5, -0.5, 0.5] and pose["t"] == [1.0, 2.0, 3.0]
    assert dict(pose) == pose.to_dict() == {"q": [0.5, 0.5, -0.5, 0.5], "t": [1.0, 2.0, 3.0]}
    assert "scale" not in pose and pose.get("scale", 1.0) == 1.0
    assert "scale" in lc.Pose(pose.q, pose.t, 2.0)
    with pytest.raises(KeyError):
        pose["center"]


def test_pose_edge_cases_an_outsider_found():
    """q that overflows its norm, q and -q at w = 0, the caller's arrays, a scale of another type."""
    with pytest.raises(ValueError, match="finite non-zero"):
        lc.Pose([1e308, 1e308, 0, 0])
    assert lc.Pose([0, 1, 0, 0]) == lc.Pose([0, -1, 0, 0])
    t = np.array([1.0, 2.0, 3.0])
    pose = lc.Pose([1, 0, 0, 0], t)
    t[0] = 99
    assert pose.t[0] == 1.0
    for bad in ("2", None, True):
        with pytest.raises(TypeError, match="scale must be a number"):
            lc.Pose(scale=bad)
