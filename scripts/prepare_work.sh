#!/usr/bin/env bash
# prepare_work.sh SCENE: build/eval/SCENE, the `eval prepare` work of the Strecha scene SCENE from
# the data folder (COLMAP on the CPU, once: reused while its prepared.json exists), with the fixed,
# public key of the evaluation's maps (figures reproducible run to run; never for a real map).
# Used by .ci/run's eval stage and the test command (scripts/test_all.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
scene="${1:?usage: scripts/prepare_work.sh SCENE (e.g. fountain-P11)}"
data="$(bash scripts/data_dir.sh)"
work=build/eval/$scene
if [ ! -d "$data/strecha/$scene/images" ]; then
  echo "error: $data/strecha/$scene is absent: run scripts/get_data.sh (or set LINECLOUD_DATA)" >&2
  exit 1
fi
dataset="$(cd "$data/strecha/$scene" && pwd)"
# A work made from another data folder (another copy, or the sets made by get_data.sh --upstream)
# is made again: its maps and figures belong to that folder's photos.
if [ -f "$work/prepared.json" ] &&
   ! grep -qF "\"dataset_dir\": \"$dataset\"" "$work/prepared.json"; then
  echo "$work was prepared from another data folder than $dataset: preparing it again"
  rm -rf "$work"
fi
if [ ! -f "$work/prepared.json" ]; then
  echo "preparing $work (COLMAP on the CPU, a few minutes, once)"
  ./build/linecloud eval prepare --dataset "$dataset" --work "$work"
fi
[ -f "$work/lifting.key" ] || (umask 077; printf '# fixed public key of the evaluation\ndirections sphere\n%s\n' \
  "$(printf '5a%.0s' $(seq 32))" > "$work/lifting.key")
