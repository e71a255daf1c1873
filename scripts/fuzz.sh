#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (ASan + UBSan) and runs each for
# SECONDS seconds (default 30), seeded with real files from ../shared/data and
# files the demo writes. Exits non-zero when a fuzzer finds a crash.
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_PER_TARGET="${1:-30}"
CC=clang CXX=clang++ cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DLINECLOUD_FUZZ=ON -DLINECLOUD_BUILD_TESTS=OFF -DLINECLOUD_BUILD_BENCH=OFF >/dev/null
cmake --build build-fuzz -j2
corpus=build-fuzz/corpus
rm -rf "$corpus" && mkdir -p "$corpus"/{lcm,bin,txt}
./build-fuzz/linecloud demo --out "$corpus/demo" --points 300 --images 4 --queries 0 >/dev/null
cp "$corpus/demo/map.lcm" "$corpus/lcm/full.lcm"
cp "$corpus/demo/map_compact.lcm" "$corpus/lcm/compact.lcm"
i=0
for f in cameras images points3D; do
  { printf "\\x$(printf %02x $i)"; cat "$corpus/demo/model/$f.bin"; } > "$corpus/bin/$f"
  i=$((i + 1))
done
shared_model="../shared/data/colmap-maupertuis/reconstruction"
if [ -d "$shared_model" ]; then
  i=0
  for f in cameras images points3D; do
    { printf "\\x$(printf %02x $i)"; head -c 20000 "$shared_model/$f.txt"; } > "$corpus/txt/$f"
    i=$((i + 1))
  done
else
  echo "note: $shared_model absent; text fuzzer starts from an empty corpus"
fi
run() {
  local target=$1 dir=$2
  echo "fuzzing $target for ${SECONDS_PER_TARGET}s"
  ./build-fuzz/"$target" -max_total_time="$SECONDS_PER_TARGET" -rss_limit_mb=2048 \
    -max_len=65536 -print_final_stats=1 "$dir" 2>&1 | grep -E "^(stat::number_of_executed_units|stat::peak_rss_mb|==|SUMMARY|Done)" || true
  # libFuzzer exits non-zero and writes crash-* files on a finding.
  if ls crash-* leak-* timeout-* oom-* >/dev/null 2>&1; then
    echo "error: $target found a failing input:"; ls crash-* leak-* timeout-* oom-* 2>/dev/null
    exit 1
  fi
}
run lcm_fuzzer "$corpus/lcm"
run colmap_binary_fuzzer "$corpus/bin"
run colmap_text_fuzzer "$corpus/txt"
echo "fuzzing finished: no crashes"
