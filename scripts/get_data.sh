#!/usr/bin/env bash
# Fills the data folder (docs/data.md) with the real data sets the README, the tests and CI use —
# Strecha's fountain-P11, Herz-Jesus-P8 and entry-P10, EuRoC V1_01 (a 32-pair excerpt), kapture's
# maupertuis COLMAP project — in the layout `linecloud eval prepare` reads, and checks every file
# against scripts/data.sha256. Says where it put them.
#   scripts/get_data.sh --from SOURCE [--to DIR]
#     SOURCE: a folder holding that layout (a mirror, another checkout's data folder) or a .tar.gz
#             of it (a path or an http(s) URL, fetched with curl).
#     DIR:    where to put the sets; default: $LINECLOUD_DATA, else data/ in the checkout.
#   scripts/get_data.sh --upstream [CHECKOUTS] [--to DIR]
#     makes the sets from their public upstream repositories: openMVG/SfM_quality_evaluation,
#     naver/kapture, MIT-SPARK/Kimera-VIO (sparse git clones from $LINECLOUD_UPSTREAM_BASE, default
#     https://github.com, ~160 MB), or from CHECKOUTS, a folder holding those three checkouts by name.
#     The sources are checked against scripts/data-upstream.sha256, then converted by
#     scripts/convert_upstream.py (needs python3-opencv and python3-numpy, see install_deps.sh).
#   scripts/get_data.sh --check [DIR]   only verify (default: the folder the tests use)
set -euo pipefail
repo="$(cd "$(dirname "$0")/.." && pwd)"
manifest="$repo/scripts/data.sha256"
from="" to="" check_only=0 upstream=0 checkouts=""
while [ $# -gt 0 ]; do
  case "$1" in
    --from) from="${2:?--from needs a folder, a .tar.gz or a URL}"; shift 2 ;;
    --upstream) upstream=1
      if [ $# -ge 2 ] && [ "${2#-}" = "$2" ]; then checkouts=$2; shift; fi
      shift ;;
    --to) to="${2:?--to needs a folder}"; shift 2 ;;
    --check) check_only=1; to="${2:-}"; [ $# -ge 2 ] && shift; shift ;;
    -h|--help) sed -n 2,18p "$0"; exit 0 ;;
    *) echo "error: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done

verify() {  # verify DIR [converted]: every file of the manifest present with its checksum
  # (converted: the re-encoded images and the ground truth, whose last digits come from the
  # conversion, only present)
  local dir=$1 converted=${2:-} bad=0
  if [ ! -d "$dir" ]; then echo "error: $dir: no such folder" >&2; return 1; fi
  while read -r sum rel; do
    if [ ! -f "$dir/$rel" ]; then echo "missing: $dir/$rel" >&2; bad=$((bad + 1)); continue; fi
    if [ -n "$converted" ]; then case "$rel" in strecha/*.jpg|euroc-v101-micro/*.jpg|*/gt/images.txt) continue ;; esac; fi
    [ "$(sha256sum < "$dir/$rel" | cut -d' ' -f1)" = "$sum" ] || { echo "checksum differs: $dir/$rel" >&2; bad=$((bad + 1)); }
  done < "$manifest"
  if [ $bad -ne 0 ]; then
    echo "error: $dir: $bad of $(wc -l < "$manifest") files missing or different (scripts/data.sha256)" >&2
    return 1
  fi
  echo "verified: $dir ($(wc -l < "$manifest") files, scripts/data.sha256)"
}

if [ $check_only -eq 1 ]; then
  verify "${to:-$(bash "$repo/scripts/data_dir.sh")}"
  exit
fi
report() {
  echo "data sets in: $(cd "$to" && pwd)"
  if [ "$(cd "$to" && pwd)" != "$(bash "$repo/scripts/data_dir.sh")" ]; then
    echo "note: the tests look in $(bash "$repo/scripts/data_dir.sh"); set LINECLOUD_DATA=$(cd "$to" && pwd)"
  fi
}

sparse_clone() {  # sparse_clone OWNER/NAME DEST PATH...: a shallow clone of only PATHs
  local url="${LINECLOUD_UPSTREAM_BASE:-https://github.com}/$1" dest=$2
  shift 2
  echo "cloning $url"
  git clone --quiet --depth 1 --filter=blob:none --sparse "$url" "$dest" 2>&1 | grep -v 'filtering not recognized' >&2 || true
  [ -d "$dest/.git" ] || { echo "error: $url: could not clone" >&2; exit 1; }
  git -C "$dest" sparse-checkout set --no-cone "$@"
}

[ $upstream -eq 0 ] || [ -z "$from" ] || { echo "error: --from and --upstream exclude each other" >&2; exit 2; }
[ $upstream -eq 1 ] || [ -n "$from" ] || { echo "error: --from SOURCE or --upstream is required (see --help)" >&2; exit 2; }
to="${to:-${LINECLOUD_DATA:-$repo/data}}"
mkdir -p "$to"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
if [ $upstream -eq 1 ]; then
  if [ -z "$checkouts" ]; then
    checkouts="$tmp/upstream"
    strecha=/Benchmarking_Camera_Calibration_2008
    sparse_clone openMVG/SfM_quality_evaluation "$checkouts/SfM_quality_evaluation" \
      "$strecha/fountain-P11/" "$strecha/Herz-Jesus-P8/" "$strecha/entry-P10/"
    sparse_clone naver/kapture "$checkouts/kapture" /samples/maupertuis/colmap/
    sparse_clone MIT-SPARK/Kimera-VIO "$checkouts/Kimera-VIO" /tests/data/MicroEurocDataset/
  fi
  echo "checking $checkouts against scripts/data-upstream.sha256"
  (cd "$checkouts" && sha256sum --quiet --strict -c "$repo/scripts/data-upstream.sha256") ||
    { echo "error: $checkouts: the upstream files above are missing or differ from scripts/data-upstream.sha256" >&2; exit 1; }
  echo "converting into $to"
  python=/usr/bin/python3; [ -x "$python" ] || python=python3
  "$python" "$repo/scripts/convert_upstream.py" "$checkouts" "$to"
  verify "$to" converted
  report
  exit
fi
case "$from" in
  http://*|https://*)
    echo "fetching $from"
    curl -fL --retry 3 -o "$tmp/data.tar.gz" "$from"
    from="$tmp/data.tar.gz" ;;
esac
if [ -f "$from" ]; then
  mkdir "$tmp/x" && tar -xzf "$from" -C "$tmp/x"
  # The archive may hold the layout at its top or in one folder.
  src="$tmp/x"
  [ -d "$src/strecha" ] || src="$(dirname "$(find "$tmp/x" -maxdepth 3 -type d -name strecha | head -1)")"
else
  src="$from"
fi
[ -d "$src" ] || { echo "error: $from: neither a folder nor a .tar.gz" >&2; exit 1; }
echo "checking $src against scripts/data.sha256"
verify "$src"
# Only the manifest's files are copied (nothing else from the source lands in the data folder).
while read -r _ rel; do
  mkdir -p "$to/$(dirname "$rel")"
  cp -p "$src/$rel" "$to/$rel"
done < "$manifest"
verify "$to"
report
