#!/usr/bin/env bash
# One clang build with AddressSanitizer + UndefinedBehaviorSanitizer (build-san) for the library's
# tests and the libFuzzer targets (scripts/fuzz.sh uses the same folder), then the tests under it.
#   scripts/sanitize.sh               build, then run the tests
#   scripts/sanitize.sh --build-only  build the tests and the fuzzers
#   scripts/sanitize.sh --test-only   run the tests of an existing build
#   scripts/sanitize.sh --configure-only   configure build-san only (scripts/fuzz.sh)
#   --all (with any of the above)     every test program, the CLI's and the service binary's too
# By default (CI) the libraries' own test programs — core (geometry, solvers, estimation, lifting,
# readers and writers, localization), features (images, SIFT, matching), privacy, serve (in
# process) — not the command line's and not those that start the real binary (they need the
# whole tool built a second time; they run in the Release test command), nor the two
# statistical attack tests whose sizes make them minutes long under the sanitizers.
set -euo pipefail
cd "$(dirname "$0")/.."
mode=all scope=libraries
for a in "$@"; do
  case "$a" in
    --build-only|--test-only|--configure-only) mode="$a" ;;
    --all) scope=all ;;
    *) echo "error: unknown argument '$a'" >&2; exit 2 ;;
  esac
done
programs=(linecloud_core_tests linecloud_features_tests linecloud_privacy_tests linecloud_serve_tests)
if [ "$mode" != "--test-only" ]; then
  # -O2 with line tables (not full debug info): stacks keep their files and lines.
  CC=clang CXX=clang++ cmake -S . -B build-san -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only -DNDEBUG" \
    -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only -DNDEBUG" \
    -DLINECLOUD_SANITIZE=ON -DLINECLOUD_FUZZ=ON -DLINECLOUD_BUILD_BENCH=OFF >/dev/null
  [ "$mode" = "--configure-only" ] && exit 0
  if [ "$scope" = all ]; then
    cmake --build build-san -j2
  else
    cmake --build build-san -j2 --target "${programs[@]}"
  fi
fi
[ "$mode" = "--build-only" ] && exit 0
filter=()
if [ "$scope" = libraries ]; then
  labels="$(IFS='|'; echo "${programs[*]}")"
  filter=(-L "^($labels)\$" -E '^(Hostile|Contract)\.|^Serve\.(FountainPhotoThroughEveryRoute|SighupReloadsAndSigtermDrainsUnderLoad)$|^(DensityAttack\.RecoversMostPointsOfADenseTexturedFacade|Resist\.KeepsPointsTheAttackCannotRecover)$')
fi
LINECLOUD_QUICK_TESTS=1 ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 \
  LSAN_OPTIONS=suppressions="$PWD/scripts/lsan.supp":print_suppressions=0 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build-san --output-on-failure -j2 "${filter[@]}"
