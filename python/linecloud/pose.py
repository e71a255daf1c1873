"""`Pose`: one type for a pose in Python, in COLMAP's and pycolmap's convention.

A pose is `target_from_source`: a point x in the source frame is `scale * R @ x + t` in the target
frame. A localization result's pose is `cam_from_world` (`rig_from_world` for a rig). `q` is the
rotation's unit quaternion (w, x, y, z). Results and JSON keep plain dicts, which serialise as they
are; `Pose.from_dict(result)` reads one, and `pose.to_dict()` writes one. A Pose is accepted
wherever a pose dict is (e.g. `cam_from_rig`)."""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np


def _matrix_from_quaternion(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def _quaternion_from_matrix(r: np.ndarray) -> np.ndarray:
    """Shepperd's method: the largest of w, x, y, z first, for accuracy."""
    trace = np.trace(r)
    k = int(np.argmax([trace, r[0, 0], r[1, 1], r[2, 2]]))
    if k == 0:
        s = 2 * np.sqrt(1 + trace)
        q = [0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    else:
        i, j, m = [(0, 1, 2), (1, 2, 0), (2, 0, 1)][k - 1]
        s = 2 * np.sqrt(1 + r[i, i] - r[j, j] - r[m, m])
        q = [0.0] * 4
        q[0] = (r[m, j] - r[j, m]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (r[j, i] + r[i, j]) / s
        q[1 + m] = (r[m, i] + r[i, m]) / s
    q = np.array(q)
    return q if q[0] >= 0 else -q


class Pose:
    """target_from_source: x_target = scale * R @ x_source + t (q = (w, x, y, z))."""

    __slots__ = ("q", "t", "scale")

    def __init__(self, q: Sequence[float] = (1.0, 0.0, 0.0, 0.0),
                 t: Sequence[float] = (0.0, 0.0, 0.0), scale: float = 1.0):
        # Copies: the caller's arrays stay the caller's.
        q = np.array(q, dtype=np.float64).reshape(-1)
        t = np.array(t, dtype=np.float64).reshape(-1)
        norm = np.linalg.norm(q) if q.shape == (4,) else 0.0
        if q.shape != (4,) or not np.all(np.isfinite(q)) or not (np.isfinite(norm) and norm > 0):
            raise ValueError(f"Pose: q must be a finite non-zero (w, x, y, z), got {q.tolist()}")
        if t.shape != (3,) or not np.all(np.isfinite(t)):
            raise ValueError(f"Pose: t must be 3 finite numbers, got {t.tolist()}")
        if isinstance(scale, (bool, str, bytes)) or not isinstance(scale, (int, float, np.number)):
            raise TypeError(f"Pose: scale must be a number, got {type(scale).__name__}")
        if not (np.isfinite(scale) and scale > 0):
            raise ValueError(f"Pose: scale must be a finite positive number, got {scale}")
        q = q / norm
        # q and -q are one rotation: the one with w > 0, or at w = 0 the first non-zero
        # component positive (so that == compares rotations).
        lead = q[np.flatnonzero(q)[0]]
        self.q = q if lead > 0 else -q
        self.t = t
        self.scale = float(scale)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "Pose":
        """A pose dict {"q", "t", "scale"?}, e.g. a localization result (its cam_from_world)."""
        if "q" not in d or "t" not in d:
            raise ValueError("Pose.from_dict: expected a dict with 'q' and 't' (a result without "
                             "a pose has none: check its 'success')")
        return cls(d["q"], d["t"], d.get("scale", 1.0))

    @classmethod
    def from_matrix(cls, m: np.ndarray) -> "Pose":
        """A 3x4 or 4x4 matrix [sR | t] (a rotation times a positive scale)."""
        m = np.asarray(m, dtype=np.float64)
        if m.shape not in ((3, 4), (4, 4)):
            raise ValueError(f"Pose.from_matrix: expected 3x4 or 4x4, got {m.shape}")
        scale = float(np.cbrt(np.linalg.det(m[:3, :3])))
        if not scale > 0:
            raise ValueError("Pose.from_matrix: the 3x3 part is not a scaled rotation")
        if abs(scale - 1.0) < 1e-12:  # a rigid matrix's determinant, to rounding
            scale = 1.0
        return cls(_quaternion_from_matrix(m[:3, :3] / scale), m[:3, 3], scale)

    @property
    def R(self) -> np.ndarray:  # noqa: N802 (the usual name)
        return _matrix_from_quaternion(self.q)

    @property
    def matrix(self) -> np.ndarray:
        """3x4 [scale * R | t]."""
        return np.hstack([self.scale * self.R, self.t[:, None]])

    @property
    def matrix4(self) -> np.ndarray:
        """4x4 [[scale * R, t], [0, 0, 0, 1]] (what from_matrix also takes)."""
        return np.vstack([self.matrix, [0.0, 0.0, 0.0, 1.0]])

    @property
    def center(self) -> np.ndarray:
        """The source frame's position of the target's origin: for cam_from_world, the camera
        centre in the world."""
        return -(self.R.T @ self.t) / self.scale

    def inverse(self) -> "Pose":
        """source_from_target."""
        w, x, y, z = self.q
        return Pose([w, -x, -y, -z], self.center, 1.0 / self.scale)

    def __matmul__(self, other: "Pose") -> "Pose":
        """a_from_b @ b_from_c = a_from_c."""
        if not isinstance(other, Pose):
            return NotImplemented
        return Pose.from_matrix(np.vstack([self.matrix, [0, 0, 0, 1]])
                                @ np.vstack([other.matrix, [0, 0, 0, 1]]))

    def transform(self, points: np.ndarray) -> np.ndarray:
        """N x 3 points from the source frame to the target frame."""
        p = np.asarray(points, dtype=np.float64)
        return self.scale * p @ self.R.T + self.t

    def to_dict(self) -> dict[str, Any]:
        """{"q": [w, x, y, z], "t": [x, y, z]} (+ "scale" when not 1): JSON-serialisable."""
        d: dict[str, Any] = {"q": self.q.tolist(), "t": self.t.tolist()}
        if self.scale != 1.0:
            d["scale"] = self.scale
        return d

    # Read as the pose dicts of results and JSON are: pose["q"], pose["t"], pose["scale"],
    # dict(pose) (estimate_pose and solve returned such dicts before they returned a Pose).
    def keys(self) -> list[str]:
        """As to_dict(): "scale" only when it is not 1."""
        return ["q", "t"] + (["scale"] if self.scale != 1.0 else [])

    def get(self, key: str, default: Any = None) -> Any:
        return self[key] if key in self else default

    def __getitem__(self, key: str) -> Any:
        if key == "q":
            return self.q.tolist()
        if key == "t":
            return self.t.tolist()
        if key == "scale":
            return self.scale
        raise KeyError(key)

    def __contains__(self, key: object) -> bool:
        return key in self.keys()

    def __eq__(self, other: object) -> bool:
        """Exactly the same pose (q, t and scale to the bit; q's sign is fixed, so q unique)."""
        if not isinstance(other, Pose):
            return NotImplemented
        return (np.array_equal(self.q, other.q) and np.array_equal(self.t, other.t)
                and self.scale == other.scale)

    __hash__ = None  # mutable, as numpy arrays are

    @classmethod
    def from_pycolmap(cls, rigid: Any) -> "Pose":
        """A pycolmap.Rigid3d (its rotation's quaternion stored as x, y, z, w) or Sim3d (with
        .scale)."""
        x, y, z, w = np.asarray(rigid.rotation.quat, dtype=np.float64).reshape(4)
        return cls([w, x, y, z], np.asarray(rigid.translation).reshape(3),
                   float(getattr(rigid, "scale", 1.0)))

    def __repr__(self) -> str:
        q = ", ".join(f"{v:.6g}" for v in self.q)
        t = ", ".join(f"{v:.6g}" for v in self.t)
        s = f", scale={self.scale:.6g}" if self.scale != 1.0 else ""
        return f"Pose(q=[{q}], t=[{t}]{s})"
