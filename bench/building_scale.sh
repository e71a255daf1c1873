#!/usr/bin/env bash
# [map]'s building-size target: a seeded synthetic model of about a million points (`linecloud
# demo`, a room seen by 120 cameras), lifted under a fresh key store and audited (the density
# attack, through its grid search beyond 200 000 lines, and the map's own crossings), each step's
# wall time and peak memory (GNU time) on this machine's cores. Prints one JSON line.
# Usage: bench/building_scale.sh [POINTS] (default 1100000: ~1 010 000 observed points, the lines)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
linecloud=${LINECLOUD:-$root/build/linecloud}
points=${1:-1100000}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export LINECLOUD_KEY_STORE="$work/keys"
step() {  # step NAME COMMAND...: runs it under GNU time, appends "NAME seconds peak_kB"
  local name=$1
  shift
  /usr/bin/time -f "$name %e %M" -a -o "$work/times" "$@" > "$work/$name.log" 2>&1 ||
    { tail -5 "$work/$name.log" >&2; exit 1; }
}
step demo "$linecloud" demo --points "$points" --images 120 --queries 1 --out "$work/demo"
step lift "$linecloud" lift --model "$work/demo/model" --out "$work/map.lcm"
step audit "$linecloud" audit --map "$work/map.lcm" --model "$work/demo/model" --out "$work/audit" --quiet
python3 - "$work" "$(nproc)" <<'PY'
import json, sys
work, cores = sys.argv[1], int(sys.argv[2])
steps = {}
for line in open(f"{work}/times"):
    name, seconds, kb = line.split()
    steps[name] = {"seconds": float(seconds), "peak_gb": round(int(kb) / 1e6, 2)}
report = json.load(open(f"{work}/audit/report.json"))
attack = report["density_attack"]
own = report["pairing_attacks"]["self_crossings"]
print(json.dumps({
    "lines": report["lines"], "cores": cores,
    "lift": steps["lift"], "audit": steps["audit"],
    "lift_and_audit_seconds": round(steps["lift"]["seconds"] + steps["audit"]["seconds"], 1),
    "density_attack": {"seconds": round(attack["seconds"], 1), "search": attack["search"],
                       "within_1_percent": attack["recovery"]["within_diagonal_percent"]["1"],
                       "lines_short_of_neighbours": attack["lines_short_of_neighbours"]},
    "self_crossings": {"seconds": round(own["seconds"], 1), "pairs": own["pairs"],
                       "share_recovered": own["share_recovered"]},
}))
PY
