"""linecloud: privacy-preserving image-based localization.

Line clouds after Speciale et al., "Privacy Preserving Image-Based Localization"
(CVPR 2019): every map point X is lifted to a 3D line through X with a random
direction and X is thrown away; a photo is localized by finding the pose where
its rays meet those lines.

Cameras are dicts ``{"model", "width", "height", "params"}`` (COLMAP's names and
parameter order); poses are ``cam_from_world`` dicts ``{"q": (w, x, y, z),
"t": (x, y, z)}`` (+ ``"scale"`` for Sim3 methods); arrays are numpy.
"""

from pathlib import Path as _Path

from . import interop
from .pose import Pose
from ._core import (
    LineCloud,
    Localizer,
    __version__,
    attack,
    attack_options,
    audit,
    audit_options,
    estimate_pose,
    lift,
    lift_options,
    localizer_options,
    map,
    memory_in_use,
    methods,
    photo_memory_mb,
    read_colmap_model,
    set_log_sink,
    set_memory_limit,
    solve,
)


def cli_path() -> str:
    """The `linecloud` command-line tool installed with this package (``python -m linecloud``);
    in a build folder (PYTHONPATH=build/python) the one built beside it."""
    here = _Path(__file__).resolve().parent
    for candidate in (here / "bin" / "linecloud", here.parent.parent / "linecloud"):
        if candidate.is_file():
            return str(candidate)
    raise FileNotFoundError(f"no linecloud tool in {here / 'bin'}: reinstall the package")


__all__ = [
    "LineCloud",
    "Localizer",
    "Pose",
    "__version__",
    "attack",
    "attack_options",
    "audit",
    "audit_options",
    "cli_path",
    "estimate_pose",
    "interop",
    "lift",
    "lift_options",
    "localizer_options",
    "map",
    "memory_in_use",
    "methods",
    "photo_memory_mb",
    "read_colmap_model",
    "set_log_sink",
    "set_memory_limit",
    "solve",
]
