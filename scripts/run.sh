#!/usr/bin/env bash
# One entry point for a fresh Debian 12 machine: installs the dependencies,
# builds (Release) and runs one job.
#   scripts/run.sh demo    the built-in synthetic demo (no data download)
#   scripts/run.sh test    every unit and end-to-end test (CTest + GoogleTest), the Python
#                          package (pip install into a venv, pytest), the console in headless
#                          chromium (web/tests), then the service behind nginx with one server
#                          killed (scripts/fault_test.sh)
#   scripts/run.sh bench   the benchmarks (Google Benchmark)
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
  # C++ tests (library, CLI, service), the Python package installed and tested, then the
  # service behind nginx with a server killed.
  test) cmake --build build -j2 && ctest --test-dir build --output-on-failure -j2 &&
        bash scripts/python_test.sh && bash scripts/build_web.sh &&
        node web/tests/console.test.mjs && bash scripts/fault_test.sh ;;
  build) cmake --build build -j2 ;;
  bench) cmake --build build -j2 && ./build/linecloud_bench ;;
  *) echo "error: unknown job '$job' (demo, test, bench, build)" >&2; exit 2 ;;
esac
