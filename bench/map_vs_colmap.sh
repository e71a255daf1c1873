#!/usr/bin/env bash
# `linecloud map` beside `colmap automatic_reconstructor` (sparse only, CPU, one camera) on the
# same photos and machine, one after the other: wall time and the cameras' error against the
# survey (gt/images.txt). Usage: bench/map_vs_colmap.sh [SCENE_DIR...] (default: the three
# Strecha scenes under $LINECLOUD_DATA). Prints one JSON line per scene.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
data=${LINECLOUD_DATA:-$root/../shared/data}
linecloud=${LINECLOUD:-$root/build/linecloud}
threads=${THREADS:-$(nproc)}
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=("$data/strecha/fountain-P11" "$data/strecha/Herz-Jesus-P8" "$data/strecha/entry-P10")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for scene in "${scenes[@]}"; do
  name=$(basename "$scene")
  gt=()
  [ -f "$scene/gt/images.txt" ] && gt=(--ground-truth "$scene/gt/images.txt")
  mkdir -p "$work/$name"
  t0=$(date +%s.%N)
  "$linecloud" map "$scene/images" --project "$work/$name/project" --out "$work/$name/maps/$name" \
    --key-store "$work/$name/keys" --threads "$threads" "${gt[@]}" --json > "$work/$name/report.json" \
    2> "$work/$name/map.log"
  t1=$(date +%s.%N)
  mkdir -p "$work/$name/colmap"
  colmap automatic_reconstructor --workspace_path "$work/$name/colmap" --image_path "$scene/images" \
    --dense 0 --use_gpu 0 --single_camera 1 --num_threads "$threads" > "$work/$name/colmap.log" 2>&1
  t2=$(date +%s.%N)
  python3 - "$work/$name/report.json" "$name" "$t0" "$t1" "$t2" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
t0, t1, t2 = map(float, sys.argv[3:6])
gt = r.get("ground_truth") or {}
print(json.dumps({"scene": sys.argv[2], "photos": r["photos"], "registered": r["registered"],
                  "points": r["points"], "map_seconds": round(t1 - t0, 1),
                  "colmap_automatic_reconstructor_seconds": round(t2 - t1, 1),
                  "ratio": round((t1 - t0) / (t2 - t1), 3),
                  "max_centre_error_extent_percent": gt.get("max_centre_error_extent_percent"),
                  "max_rotation_error_deg": gt.get("max_rotation_error_deg"),
                  "stages": {s["name"]: round(s["seconds"], 1) for s in r["stages"]}}))
PY
done
