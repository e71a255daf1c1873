#!/usr/bin/env bash
# One clang build with AddressSanitizer + UndefinedBehaviorSanitizer for two jobs: the libFuzzer
# targets (scripts/fuzz.sh) and the tests (scripts/sanitize.sh) — the library is compiled once.
# Needs clang (apt-get install clang; scripts/install_deps.sh clang).
set -euo pipefail
cd "$(dirname "$0")/.."
command -v clang++ >/dev/null || { echo "error: the sanitizer build needs clang++ (apt-get install clang)" >&2; exit 2; }
CC=clang CXX=clang++ cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DLINECLOUD_FUZZ=ON -DLINECLOUD_BUILD_BENCH=OFF >/dev/null
cmake --build build-asan -j2
