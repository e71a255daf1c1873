#!/usr/bin/env bash
# Installs linecloud's build dependencies from Debian 12's archive (apt-get).
# Does nothing when they are all present. Extra packages may be passed as
# arguments (CI adds clang for the fuzzers).
set -euo pipefail
packages=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev libsqlite3-dev libsodium-dev libcli11-dev nlohmann-json3-dev libfmt-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libopengv-dev  # a peer in the solver benchmark only
  libceres-dev   # the peer of our LM in the refinement benchmark only
  libcairo2-dev  # eval: PNG plots
  libvlfeat-dev libfreeimage-dev  # features: SIFT as COLMAP's CPU extractor, image decoding
  libflann-dev liblz4-dev  # features: approximate nearest neighbours for large maps
  libopencv-features2d-dev  # features: OpenCV's SIFT, the fast extractor
  libfaiss-dev libhnswlib-dev  # features: the matching index (FAISS), a peer (hnswlib)
  libopenblas0-openmp  # BLAS for FAISS's k-means and coarse search (Debian's default is slower)
  colmap         # eval: structure from motion (its command line)
  libmicrohttpd-dev  # serve: HTTP/1.1 (the server)
  libcpp-httplib-dev  # serve: HTTP clients (load generator, tests)
  nginx-light wrk     # serve: the deployment example's fault test and load test
  # python: `import linecloud` (pybind11), its tests (pytest, OpenCV's SIFT as another
  # extractor) and an offline `pip install` into a virtual environment
  python3 python3-dev python3-venv python3-setuptools python3-wheel pybind11-dev python3-numpy
  python3-pytest python3-opencv
  chromium  # web: the console's browser test (headless, driven by playwright-core from npm)
  "$@"
)
# Node.js and npm for the console (the machine's own when present: Debian 12's is 18, enough).
command -v npm >/dev/null 2>&1 || packages+=(nodejs npm)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
echo "installing: ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
# CI (a throwaway machine) skips dpkg's fsync per file: LINECLOUD_APT_UNSAFE_IO=1.
unsafe=()
[ "${LINECLOUD_APT_UNSAFE_IO:-0}" = 1 ] && unsafe=(-o Dpkg::Options::=--force-unsafe-io)
$SUDO apt-get install -y -qq --no-install-recommends "${unsafe[@]}" "${missing[@]}" >/dev/null
