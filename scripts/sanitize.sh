#!/usr/bin/env bash
# One clang build with AddressSanitizer + UndefinedBehaviorSanitizer (build-san) for the tests and
# the libFuzzer targets (scripts/fuzz.sh uses the same folder), then the tests under it.
#   scripts/sanitize.sh               build, then run the tests
#   scripts/sanitize.sh --build-only  build the tests, the fuzzers and the executable
#   scripts/sanitize.sh --test-only   run the tests of an existing build
set -euo pipefail
cd "$(dirname "$0")/.."
mode="${1:-all}"
if [ "$mode" != "--test-only" ]; then
  CC=clang CXX=clang++ cmake -S . -B build-san -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DLINECLOUD_SANITIZE=ON -DLINECLOUD_FUZZ=ON -DLINECLOUD_BUILD_BENCH=OFF >/dev/null
  cmake --build build-san -j2
fi
[ "$mode" = "--build-only" ] && exit 0
LINECLOUD_QUICK_TESTS=1 ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 \
  LSAN_OPTIONS=suppressions="$PWD/scripts/lsan.supp":print_suppressions=0 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build-san --output-on-failure -j2
