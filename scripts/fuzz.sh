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
  json_fuzzer colmap_database_fuzzer image_fuzzer index_cache_fuzzer http_fuzzer key_store_fuzzer
# The seed files come from the demo of the Release build (scripts/run.sh), else of this one.
tool=./build/linecloud
if [ ! -x "$tool" ]; then cmake --build build-san -j2 --target linecloud; tool=./build-san/linecloud; fi
corpus=build-san/corpus
rm -rf "$corpus" && mkdir -p "$corpus"/{lcm,bin,txt,json,db,image,cache,http,keys}
"$tool" demo --out "$corpus/demo" --points 300 --images 4 --queries 1 >/dev/null
# A ledger and a key bundle: the demo's model lifted into a store of the corpus, then exported.
LINECLOUD_KEY_STORE="$corpus/store" "$tool" lift --model "$corpus/demo/model" \
  --out "$corpus/lifted.lcm" --quiet >/dev/null
LINECLOUD_KEY_STORE="$corpus/store" "$tool" keys export --model "$corpus/demo/model" \
  --out "$corpus/bundle" >/dev/null
{ printf '\x00'; cat "$corpus"/store/*.ledger; } > "$corpus/keys/ledger"
{ printf '\x01'; cat "$corpus/bundle"; } > "$corpus/keys/bundle"
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
# Two targets at a time (each fuzzer is one process on one core; the machine has two): every
# target still gets its SECONDS of wall time. Findings go to build-san/artifacts/TARGET-*.
artifacts=build-san/artifacts
rm -rf "$artifacts" && mkdir -p "$artifacts"
targets=()
run() { targets+=("$1 $2"); }
run_one() {
  local target=$1 dir=$2
  ./build-san/"$target" -max_total_time="$SECONDS_PER_TARGET" -rss_limit_mb=2048 \
    -max_len=65536 -print_final_stats=1 -artifact_prefix="$artifacts/$target-" "$dir" \
    > "build-san/fuzz-$target.log" 2>&1 || true
}
run_all() {
  for spec in "${targets[@]}"; do
    set -- $spec
    echo "fuzzing $1 for ${SECONDS_PER_TARGET}s"
    run_one "$1" "$2" &
    while [ "$(jobs -rp | wc -l)" -ge 2 ]; do wait -n || true; done
  done
  wait
  for spec in "${targets[@]}"; do
    set -- $spec
    echo "== $1"
    grep -E "^(stat::number_of_executed_units|stat::peak_rss_mb|==|SUMMARY|Done)" \
      "build-san/fuzz-$1.log" || true
  done
  # libFuzzer exits non-zero and writes crash-/leak-/timeout-/oom- files on a finding.
  if [ -n "$(ls -A "$artifacts")" ]; then
    echo "error: a fuzzer found a failing input:"; ls "$artifacts"
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
# Requests: what clients send (docs/http_api.md), as bytes on a connection.
printf 'GET /healthz HTTP/1.1\r\nHost: a\r\n\r\n' > "$corpus/http/healthz"
printf 'GET /v1/maps HTTP/1.1\r\nHost: a\r\nAuthorization: Bearer alice-secret\r\n\r\n' > "$corpus/http/maps"
printf 'GET /v1/maps/synth/segments?limit=5 HTTP/1.1\r\nHost: a\r\nAuthorization: Bearer root-secret\r\n\r\n' > "$corpus/http/segments"
body='{"camera": {"model": "PINHOLE", "width": 640, "height": 480, "params": [500, 500, 320, 240]}, "keypoints": [[1, 2], [3, 4]], "descriptors": "'"$(head -c 256 /dev/zero | base64 -w0)"'"}'
printf 'POST /v1/maps/synth/localize HTTP/1.1\r\nHost: a\r\nAuthorization: Bearer alice-secret\r\nContent-Type: application/json\r\nContent-Length: %d\r\n\r\n%s' "${#body}" "$body" > "$corpus/http/localize"
geo='{"id": "q", "timestamp": 0, "type": "geopose", "sensors": [{"id": "c", "type": "camera"}], "sensorReadings": {"cameraReadings": [{"sensorId": "c", "imageFormat": "GRAY8", "size": [8, 8], "imageBytes": "'"$(head -c 64 /dev/zero | base64 -w0)"'", "params": {"model": "PINHOLE", "modelParams": [5, 5, 4, 4]}}]}}'
printf 'POST /geopose?map=synth HTTP/1.1\r\nHost: a\r\nAuthorization: Bearer root-secret\r\nContent-Type: application/json\r\nContent-Length: %d\r\n\r\n%s' "${#geo}" "$geo" > "$corpus/http/geopose"
form=$'--B\r\nContent-Disposition: form-data; name="camera"\r\n\r\nPINHOLE 8 8 5 5 4 4\r\n--B\r\nContent-Disposition: form-data; name="image"; filename="a.png"\r\n\r\n\x89PNG\r\n\x1a\n\r\n--B--\r\n'
printf 'POST /v1/maps/synth/localize HTTP/1.1\r\nHost: a\r\nAuthorization: Bearer root-secret\r\nContent-Type: multipart/form-data; boundary=B\r\nContent-Length: %d\r\n\r\n%s' "${#form}" "$form" > "$corpus/http/multipart"
run index_cache_fuzzer "$corpus/cache"
run http_fuzzer "$corpus/http"
run key_store_fuzzer "$corpus/keys"
run_all
echo "fuzzing finished: no crashes"
