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


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        build = Path(os.environ.get("LINECLOUD_CMAKE_BUILD_DIR", ROOT / "build" / "pip")).resolve()
        configure = ["cmake", "-S", str(ROOT), "-B", str(build), "-DLINECLOUD_PYTHON=ON"]
        if not (build / "CMakeCache.txt").exists():
            generator = ["-G", "Ninja"] if shutil.which("ninja") else []
            configure += generator + [
                "-DCMAKE_BUILD_TYPE=Release", "-DLINECLOUD_BUILD_TESTS=OFF",
                "-DLINECLOUD_BUILD_BENCH=OFF", "-DLINECLOUD_INSTALL=OFF",
                f"-DPython3_EXECUTABLE={sys.executable}"]
        subprocess.run(configure, check=True)
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL", str(os.cpu_count() or 1))
        subprocess.run(["cmake", "--build", str(build), "--target", "linecloud_python", "-j", jobs],
                       check=True)
        built = list((build / "python" / "linecloud").glob("_core*.so"))
        if len(built) != 1:
            raise RuntimeError(f"{build}/python/linecloud: expected one _core module, got {built}")
        target = Path(self.get_ext_fullpath(ext.name))
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(built[0], target)


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
    zip_safe=False,
)
