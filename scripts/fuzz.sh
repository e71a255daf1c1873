#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (ASan + UBSan) and runs each for
# SECONDS seconds (default 30), seeded with real files from the data folder (scripts/data_dir.sh) and
# files the demo writes. Exits non-zero when a fuzzer finds a crash.
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_PER_TARGET="${1:-30}"
# The sanitizer build's folder, configured by scripts/sanitize.sh: one clang ASan + UBSan build for both.
bash scripts/sanitize.sh --configure-only
cmake --build build-san -j2 --target lcm_fuzzer colmap_binary_fuzzer colmap_text_fuzzer \
  json_fuzzer colmap_database_fuzzer image_fuzzer index_cache_fuzzer
# The seed files come from the demo of the Release build (scripts/run.sh), else of this one.
tool=./build/linecloud
if [ ! -x "$tool" ]; then cmake --build build-san -j2 --target linecloud; tool=./build-san/linecloud; fi
corpus=build-san/corpus
rm -rf "$corpus" && mkdir -p "$corpus"/{lcm,bin,txt,json,db,image,cache}
"$tool" demo --out "$corpus/demo" --points 300 --images 4 --queries 1 >/dev/null
cp "$corpus/demo/map.lcm" "$corpus/lcm/full.lcm"
cp "$corpus/demo/map_compact.lcm" "$corpus/lcm/compact.lcm"
i=0
for f in cameras images points3D; do
  { printf "\\x$(printf %02x $i)"; cat "$corpus/demo/model/$f.bin"; } > "$corpus/bin/$f"
  i=$((i + 1))
done
data="$(bash scripts/data_dir.sh)"
shared_model="$data/colmap-maupertuis/reconstruction"
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
  ./build-san/"$target" -max_total_time="$SECONDS_PER_TARGET" -rss_limit_mb=2048 \
    -max_len=65536 -print_final_stats=1 "$dir" 2>&1 | grep -E "^(stat::number_of_executed_units|stat::peak_rss_mb|==|SUMMARY|Done)" || true
  # libFuzzer exits non-zero and writes crash-* files on a finding.
  if ls crash-* leak-* timeout-* oom-* >/dev/null 2>&1; then
    echo "error: $target found a failing input:"; ls crash-* leak-* timeout-* oom-* 2>/dev/null
    exit 1
  fi
}
# JSON inputs: the demo's query (reader 0), a solve problem (1), and a
# prepared.json when a CI evaluation left one (2).
{ printf '\x00'; cat "$corpus/demo/queries/query_000.json" 2>/dev/null || echo '{}'; } > "$corpus/json/query"
{ printf '\x01'; echo '{"method": "p3P", "bearings": [[0,0,1],[0.1,0,1],[0,0.1,1]], "points": [[0,0,5],[0.5,0,5],[0,0.5,5]]}'; } > "$corpus/json/problem"
for prepared in build/eval/*/prepared.json; do
  [ -f "$prepared" ] && { printf '\x02'; head -c 60000 "$prepared"; } > "$corpus/json/prepared" && break
done
# A COLMAP database: an empty one as COLMAP creates it (its schema), when
# COLMAP's CLI is installed.
if command -v colmap >/dev/null; then
  colmap database_creator --database_path "$corpus/db/empty.db" >/dev/null 2>&1 || true
fi
# Photos: two small JPEGs of the shared model and a bare PNG signature; the
# index cache starts empty (its reader refuses all but authenticated files).
if [ -d "$data/colmap-maupertuis/images" ]; then
  cp "$data"/colmap-maupertuis/images/0[01].jpg "$corpus/image/"
fi
printf '\x89PNG\r\n\x1a\n' > "$corpus/image/signature.png"
run lcm_fuzzer "$corpus/lcm"
run colmap_binary_fuzzer "$corpus/bin"
run colmap_text_fuzzer "$corpus/txt"
run json_fuzzer "$corpus/json"
run colmap_database_fuzzer "$corpus/db"
run image_fuzzer "$corpus/image"
run index_cache_fuzzer "$corpus/cache"
echo "fuzzing finished: no crashes"
