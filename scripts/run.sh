#!/usr/bin/env bash
# One entry point for a fresh Debian 12 machine: installs the dependencies,
# builds (Release) and runs one job.
#   scripts/run.sh demo    the built-in synthetic demo (no data download)
#   scripts/run.sh test    every test, none skipped (scripts/test_all.sh): prepares the real-data
#                          works (fountain-P11, Herz-Jesus-P8 through COLMAP, once), then CTest,
#                          the Python package (pip install into a venv, pytest), the console in
#                          headless Chromium, the service behind nginx with a server killed
#   scripts/run.sh bench   the benchmarks (Google Benchmark)
#   scripts/run.sh python  the Python package in a virtual environment ./env (Debian's python3,
#                          its numpy): `env/bin/python -c "import linecloud"`, `env/bin/linecloud`
#   scripts/run.sh build   only the build (everything: library, tools, tests, benchmarks, module)
set -euo pipefail
cd "$(dirname "$0")/.."
job="${1:-demo}"
bash scripts/install_deps.sh
# Debian's own Python for the module (not a pyenv or conda one found first on PATH).
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DLINECLOUD_PYTHON=ON \
  -DPython3_EXECUTABLE=/usr/bin/python3 >/dev/null
case "$job" in
  # The demo needs only the executable, not the tests and benchmarks.
  demo) cmake --build build -j2 --target linecloud && ./build/linecloud demo ;;
  # Every test, none skipped: the real-data works prepared (COLMAP, once), the C++ tests, the
  # Python package, the console in Chromium, the service behind nginx; a table at the end.
  test) cmake --build build -j2 && bash scripts/test_all.sh ;;
  build) cmake --build build -j2 ;;
  python) cmake --build build -j2 --target linecloud_python linecloud &&
          /usr/bin/python3 -m venv --system-site-packages env &&
          env/bin/pip install --quiet --no-index --no-build-isolation --disable-pip-version-check . &&
          (cd / && "$OLDPWD/env/bin/python" -c 'import linecloud; print("linecloud", linecloud.__version__, "in", linecloud.__file__)') ;;
  bench) cmake --build build -j2 && ./build/linecloud_bench ;;
  *) echo "error: unknown job '$job' (demo, test, python, bench, build)" >&2; exit 2 ;;
esac
