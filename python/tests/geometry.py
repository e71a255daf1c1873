"""Small numpy geometry for the tests: quaternions (w, x, y, z), poses, errors."""

import numpy as np


def quat_to_matrix(q):
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def random_rotation(rng):
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def rotation_error_deg(q_a, q_b):
    r = quat_to_matrix(q_a).T @ quat_to_matrix(q_b)
    return np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1)))


def centre(pose):
    return -quat_to_matrix(pose["q"]).T @ np.asarray(pose["t"])


def lines_through(points, rng):
    """Pluecker lines (v, w = X x v) through `points` with random directions."""
    v = rng.normal(size=points.shape)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return np.hstack([v, np.cross(points, v)])


def synthetic_instance(rng, n=200, outliers=0.3, noise_px=0.0):
    """A PINHOLE camera looking at points 4-8 units ahead; returns camera dict,
    true pose, 2D points, 3D points and the inlier mask."""
    camera = {"model": "PINHOLE", "width": 1000, "height": 800, "params": [800.0, 800.0, 500.0, 400.0]}
    q = random_rotation(rng)
    t = rng.normal(size=3)
    R = quat_to_matrix(q)
    xy = np.column_stack([rng.uniform(50, 950, n), rng.uniform(50, 750, n)])
    depth = rng.uniform(4, 8, n)
    rays = np.column_stack([(xy[:, 0] - 500) / 800, (xy[:, 1] - 400) / 800, np.ones(n)])
    x_cam = rays * depth[:, None]
    points = (x_cam - t) @ R  # R^T (x - t), row-wise
    inlier = rng.uniform(size=n) >= outliers
    observed = xy + rng.normal(scale=noise_px, size=xy.shape) if noise_px else xy.copy()
    observed[~inlier] = np.column_stack([rng.uniform(0, 1000, (~inlier).sum()),
                                         rng.uniform(0, 800, (~inlier).sum())])
    return camera, {"q": q, "t": t}, observed, points, inlier


def line_distance_px(line, pose, xy, focal=800.0, principal=(500.0, 400.0)):
    """Pixel distance of `xy` from the projection of Pluecker line (v, w) by
    cam_from_world `pose` (PINHOLE, one focal length)."""
    R = quat_to_matrix(pose["q"])
    t = np.asarray(pose["t"])
    v, w = R @ line[:3], R @ line[3:] + np.cross(t, R @ line[:3])
    x = np.array([(xy[0] - principal[0]) / focal, (xy[1] - principal[1]) / focal, 1.0])
    return focal * abs(w @ x) / np.hypot(w[0], w[1])


def separate_line_outliers(rng, lines, pose, xy, inlier, min_px=20.0):
    """Moves each outlier's 2D point until it is at least `min_px` from its
    line's projection (a random 2D point can lie on it by chance)."""
    xy = xy.copy()
    for i in np.flatnonzero(~inlier):
        while line_distance_px(lines[i], pose, xy[i]) < min_px:
            xy[i] = [rng.uniform(0, 1000), rng.uniform(0, 800)]
    return xy
