"""Type stubs of linecloud._core (the compiled module)."""

from os import PathLike
from typing import Any, BinaryIO, Sequence, TypedDict, Union

import numpy as np
import numpy.typing as npt

__version__: str

_Path = Union[str, PathLike[str]]


class Camera(TypedDict):
    model: str  # COLMAP's name: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, ...
    width: int
    height: int
    params: Sequence[float]  # COLMAP's order


class Pose(TypedDict, total=False):
    q: Sequence[float]  # (w, x, y, z), cam_from_world (rig_from_world for m- methods)
    t: Sequence[float]
    scale: float  # Sim3 methods only


class LineCloud:
    def __init__(self, lines: npt.ArrayLike, ids: npt.ArrayLike,
                 descriptors: npt.NDArray[np.uint8] | None = None) -> None: ...
    @staticmethod
    def read(path: _Path) -> LineCloud: ...
    def write(self, path: _Path) -> None: ...
    def __len__(self) -> int: ...
    @property
    def lines(self) -> npt.NDArray[np.float64]: ...  # N x 6: v, w
    @property
    def ids(self) -> npt.NDArray[np.uint64]: ...
    @property
    def descriptors(self) -> npt.NDArray[np.uint8] | None: ...
    @property
    def encoding(self) -> str: ...
    @property
    def gravity(self) -> tuple[float, float, float] | None: ...
    def info(self) -> dict[str, Any]: ...


def lift(model_dir: _Path, database: _Path | None = None, out: _Path | None = None,
         key_store: _Path | None = None, key_file: _Path | None = None, compact: bool = False,
         force: bool = False) -> LineCloud: ...


def read_colmap_model(path: _Path) -> dict[str, Any]: ...


_Image = Union[_Path, bytes, bytearray, memoryview, BinaryIO, npt.NDArray[np.uint8]]


class Localizer:
    def __init__(self, cloud_or_path: LineCloud | _Path, method: str | None = None,
                 threads: int = 1, *, features: str = ..., index: str = ..., nprobe: int = ...,
                 max_ratio: float = ..., cross_check: bool = ..., exact_matching: bool = ...,
                 max_pixels: int = ..., threshold: float = ..., seed: int = ...,
                 refine: bool = ..., max_seconds: float = ..., min_inliers: int = ...,
                 map_gravity: Sequence[float] | None = ...) -> None: ...
    def localize_image(self, image: _Image | Sequence[_Image],
                       camera: Camera | Sequence[Camera], **options: Any) -> dict[str, Any]: ...
    def localize_features(self, keypoints: npt.ArrayLike | Sequence[npt.ArrayLike],
                          descriptors: npt.NDArray[np.uint8] | Sequence[npt.NDArray[np.uint8]],
                          camera: Camera | Sequence[Camera], **options: Any) -> dict[str, Any]: ...
    def localize_query(self, query: dict[str, Any], **options: Any) -> dict[str, Any]: ...
    @property
    def size(self) -> int: ...
    @property
    def has_descriptors(self) -> bool: ...
    def __len__(self) -> int: ...


def estimate_pose(method: str, points2D: npt.ArrayLike | Sequence[npt.ArrayLike],
                  lines_or_points3D: npt.ArrayLike | Sequence[npt.ArrayLike],
                  camera: Camera | Sequence[Camera], *, ransac: dict[str, Any] | None = None,
                  refine: bool | dict[str, Any] | None = None,
                  success: bool | dict[str, Any] | None = None,
                  gravity: Sequence[float] | None = None,
                  map_gravity: Sequence[float] | None = None,
                  points_local: npt.ArrayLike | None = None,
                  cam_from_rig: Sequence[Pose] | None = None) -> tuple[Pose | None, dict[str, Any]]: ...


def solve(method: str, **sample: Any) -> list[Pose]: ...


def methods() -> list[dict[str, Any]]: ...


def attack(cloud: LineCloud | _Path, **options: Any) -> npt.NDArray[np.float64]: ...


def audit(cloud: LineCloud | _Path, model_dir: _Path, **options: Any) -> dict[str, Any]: ...
