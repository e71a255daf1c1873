#!/usr/bin/env bash
# [rebuild] docs/lifting.md's table, one scene: the released map is `eval prepare`'s (WORK), the
# second version a rebuild from a new database (COLMAP's SIFT at max_image_size 800, exhaustive
# matching, mapper with the intrinsics fixed), lifted as it is and aligned to the released frame
# first (colmap model_aligner through the camera centres), at --same-place 1e-3 and 3e-3, both
# versions into one fresh key store; then the attacker's view (audit --other: the two maps aligned
# from the files, one estimate per line) within 1e-4 and 1e-3 of the diagonal.
#   bench/rebuild_attack.sh build/eval/fountain-P11 OUT_DIR
set -euo pipefail
work=$(cd "$1" && pwd); out=$2; lc=${LINECLOUD:-$(cd "$(dirname "$0")/.." && pwd)/build/linecloud}
data=$(bash "$(dirname "$0")/../scripts/data_dir.sh")
scene=$(/usr/bin/python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['dataset'])" "$work/prepared.json")
images="$data/strecha/$scene/images"
cam=$(/usr/bin/python3 -c "import json,sys; c=json.load(open(sys.argv[1]))['cameras'][0]; print(','.join(map(str, c['params'])))" "$work/prepared.json")
mkdir -p "$out/v2/sparse" "$out/v2-aligned" "$out/v1txt"
if [ ! -f "$out/v2/sparse/0/points3D.bin" ]; then
  colmap feature_extractor --database_path "$out/v2/database.db" --image_path "$images" \
    --ImageReader.camera_model PINHOLE --ImageReader.single_camera 1 --ImageReader.camera_params "$cam" \
    --SiftExtraction.max_image_size 800 --SiftExtraction.use_gpu 0 > "$out/v2/log.txt" 2>&1
  colmap exhaustive_matcher --database_path "$out/v2/database.db" --SiftMatching.use_gpu 0 >> "$out/v2/log.txt" 2>&1
  colmap mapper --database_path "$out/v2/database.db" --image_path "$images" --output_path "$out/v2/sparse" \
    --Mapper.ba_refine_focal_length 0 --Mapper.ba_refine_principal_point 0 \
    --Mapper.ba_refine_extra_params 0 >> "$out/v2/log.txt" 2>&1
  # The released images' centres, for model_aligner.
  colmap model_converter --input_path "$work/colmap/sparse/0" --output_path "$out/v1txt" --output_type TXT > /dev/null
  /usr/bin/python3 - "$out/v1txt/images.txt" > "$out/centres.txt" <<'PY'
import sys
rows = [l.split() for l in open(sys.argv[1]) if not l.startswith('#')][0::2]
for f in rows:
    w, x, y, z = map(float, f[1:5]); t = list(map(float, f[5:8]))
    r = [[1-2*(y*y+z*z), 2*(x*y-z*w), 2*(x*z+y*w)], [2*(x*y+z*w), 1-2*(x*x+z*z), 2*(y*z-x*w)],
         [2*(x*z-y*w), 2*(y*z+x*w), 1-2*(x*x+y*y)]]
    print(f[9], *[-sum(r[k][i] * t[k] for k in range(3)) for i in range(3)])
PY
  colmap model_aligner --input_path "$out/v2/sparse/0" --output_path "$out/v2-aligned" \
    --ref_images_path "$out/centres.txt" --ref_is_gps 0 --robust_alignment 1 \
    --robust_alignment_max_error 0.05 >> "$out/v2/log.txt" 2>&1
fi
echo "| version | --same-place | within 1e-4: recovered / beyond density | within 1e-3 | nearest line within 1e-3, beyond the map |"
for version in v2/sparse/0 v2-aligned; do
  for same in 1e-3 3e-3; do
    run="$out/run-${version//\//-}-$same"; rm -rf "$run"; mkdir -p "$run"
    export LINECLOUD_KEY_STORE="$run/keys"
    "$lc" lift --model "$work/colmap/sparse/0" --database "$work/colmap/database.db" --out "$run/v1.lcm" --quiet > /dev/null
    "$lc" lift --model "$out/$version" --database "$out/v2/database.db" --out "$run/v2.lcm" --same-place $same > "$run/lift.txt"
    for w in 1e-4 1e-3; do
      "$lc" audit --map "$run/v1.lcm" --model "$work/colmap/sparse/0" --other "$run/v2.lcm" \
        --recovered-within $w --out "$run/audit$w" > /dev/null
    done
    /usr/bin/python3 - "$run" "$version" "$same" <<'PY'
import json, sys
run, version, same = sys.argv[1:]
cells = []
for w in ['1e-4', '1e-3']:
    p = json.load(open(f'{run}/audit{w}/report.json'))['pairing_attacks']['aligned_by_descriptor']
    cells.append(f"{p['recovered']} / {p['recovered_beyond_density']} ({100 * p['share_recovered_beyond_density']:.2f} %)")
l = json.load(open(f'{run}/audit1e-3/report.json'))['pairing_attacks']['aligned_by_nearest_line']
print(f"| {version} | {same} | {cells[0]} | {cells[1]} | {l['recovered_beyond_map']} |")
PY
  done
done
