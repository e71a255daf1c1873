#!/usr/bin/env bash
# The Python package as a user installs it: a virtual environment of Debian's
# Python (seeing Debian's numpy, pytest and OpenCV), `pip install
# --no-build-isolation .` offline from the build folder that `scripts/run.sh`
# built, then the pytest suite against the installed package.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=build/venv
/usr/bin/python3 -m venv --clear --system-site-packages "$venv"
LINECLOUD_CMAKE_BUILD_DIR="$PWD/build" "$venv/bin/pip" install --quiet --no-index \
  --no-build-isolation --disable-pip-version-check .
# Imported from the environment, not from the source tree.
python="$PWD/$venv/bin/python"
(cd / && "$python" -c 'import linecloud; print("linecloud", linecloud.__version__, "from", linecloud.__file__)')
# The tests use the package's own command-line tool (installed with it: `python -m linecloud`).
(cd / && "$OLDPWD/$venv/bin/linecloud" --version)
"$venv/bin/python" -m pytest -q -p no:cacheprovider python/tests
