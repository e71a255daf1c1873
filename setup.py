"""pip install --no-build-isolation .   (offline, Debian 12's python3-setuptools)

setuptools drives the project's CMake build (-DLINECLOUD_PYTHON=ON) for the
module linecloud._core, as PoseLib's setup.py does. LINECLOUD_CMAKE_BUILD_DIR
names a build folder to reuse (e.g. the one `scripts/run.sh test` built);
otherwise build/pip is configured with the libraries only.
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent


def _version() -> str:
    for line in (ROOT / "CMakeLists.txt").read_text().splitlines():
        if line.startswith("project(linecloud VERSION "):
            return line.split("VERSION ")[1].split()[0]
    raise RuntimeError("CMakeLists.txt: no project version")


def _build_dir() -> Path:
    """LINECLOUD_CMAKE_BUILD_DIR; else ./build when it is a configured build with the module on
    (the one `scripts/run.sh` makes: nothing is compiled again); else build/pip."""
    if os.environ.get("LINECLOUD_CMAKE_BUILD_DIR"):
        return Path(os.environ["LINECLOUD_CMAKE_BUILD_DIR"]).resolve()
    cache = ROOT / "build" / "CMakeCache.txt"
    if cache.exists() and "LINECLOUD_PYTHON:BOOL=ON" in cache.read_text(errors="replace"):
        return ROOT / "build"
    return ROOT / "build" / "pip"


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        build = _build_dir()
        configure = ["cmake", "-S", str(ROOT), "-B", str(build), "-DLINECLOUD_PYTHON=ON"]
        if not (build / "CMakeCache.txt").exists():
            generator = ["-G", "Ninja"] if shutil.which("ninja") else []
            configure += generator + [
                "-DCMAKE_BUILD_TYPE=Release", "-DLINECLOUD_BUILD_TESTS=OFF",
                "-DLINECLOUD_BUILD_BENCH=OFF", "-DLINECLOUD_INSTALL=OFF",
                f"-DPython3_EXECUTABLE={sys.executable}"]
        print(f"linecloud: CMake build folder {build}", flush=True)
        subprocess.run(configure, check=True)
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL", str(os.cpu_count() or 1))
        # The module and the command-line tool (shipped in the package: `python -m linecloud`).
        subprocess.run(["cmake", "--build", str(build), "--target", "linecloud_python", "linecloud",
                        "-j", jobs], check=True)
        built = list((build / "python" / "linecloud").glob("_core*.so"))
        if len(built) != 1:
            raise RuntimeError(f"{build}/python/linecloud: expected one _core module, got {built}")
        target = Path(self.get_ext_fullpath(ext.name))
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(built[0], target)
        tool = target.parent / "bin" / "linecloud"
        tool.parent.mkdir(exist_ok=True)
        shutil.copy2(build / "linecloud", tool)


setup(
    name="linecloud",
    version=_version(),
    description="Privacy-preserving image-based localization with line clouds "
                "(Speciale et al., CVPR 2019)",
    license="BSD-3-Clause",
    python_requires=">=3.9",
    install_requires=["numpy"],
    packages=["linecloud"],
    package_dir={"": "python"},
    package_data={"linecloud": ["py.typed", "*.pyi"]},
    ext_modules=[Extension("linecloud._core", sources=[])],
    cmdclass={"build_ext": CMakeBuild},
    entry_points={"console_scripts": ["linecloud = linecloud.__main__:main"]},
    zip_safe=False,
)
