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
    --to) [ -n "${2:-}" ] || { echo "error: --to needs a folder" >&2; exit 2; }
      to=$2; shift 2 ;;
    --check) check_only=1; to="${2:-}"; [ $# -ge 2 ] && shift; shift ;;
    -h|--help) sed -n 2,18p "$0"; exit 0 ;;
    *) echo "error: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done

# A folder made by --upstream holds this file: its re-encoded images and ground truth (whose last
# digits come from the conversion) are checked for presence only.
upstream_mark=.made-by-get-data-upstream

extra_files() {  # extra_files DIR MANIFEST NAME FOLDER...: files named NAME (a glob) in the FOLDERs
  # (under DIR) that the MANIFEST does not list
  local dir=$1 list=$2 name=$3
  shift 3
  (cd "$dir" && for folder in "$@"; do [ ! -d "$folder" ] || find "$folder" -maxdepth 1 -type f -name "$name"; done) |
    sort | comm -23 - <(awk '{print $2}' "$list" | sort)
}

verify() {  # verify DIR [strict]: every file of the manifest present with its checksum, no stray
  # photo (strict: a folder --upstream made is held to the reference's checksums too)
  local dir=$1 strict=${2:-} converted="" bad=0 extra
  if [ ! -d "$dir" ]; then echo "error: $dir: no such folder" >&2; return 1; fi
  [ -n "$strict" ] || [ ! -f "$dir/$upstream_mark" ] || converted=1
  while read -r sum rel; do
    if [ ! -f "$dir/$rel" ]; then echo "missing: $dir/$rel" >&2; bad=$((bad + 1)); continue; fi
    if [ -n "$converted" ]; then case "$rel" in strecha/*.jpg|euroc-v101-micro/*.jpg|*/gt/images.txt) continue ;; esac; fi
    [ "$(sha256sum < "$dir/$rel" | cut -d' ' -f1)" = "$sum" ] || { echo "checksum differs: $dir/$rel" >&2; bad=$((bad + 1)); }
  done < "$manifest"
  # eval prepare reads every photo of an images/ folder: one the manifest does not list is an error.
  extra=$(extra_files "$dir" "$manifest" '*' $(awk '{print $2}' "$manifest" | grep '/images/' | xargs -n1 dirname | sort -u))
  if [ -n "$extra" ]; then
    echo "$extra" | sed "s|^|not in scripts/data.sha256: $dir/|" >&2
    bad=$((bad + $(echo "$extra" | wc -l)))
  fi
  if [ $bad -ne 0 ]; then
    echo "error: $dir: $bad files missing, different or not in scripts/data.sha256 ($(wc -l < "$manifest") listed)" >&2
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
  [ -d "$checkouts" ] || { echo "error: $checkouts: no such folder" >&2; exit 1; }
  echo "checking $checkouts against scripts/data-upstream.sha256"
  (cd "$checkouts" && sha256sum --quiet --strict -c "$repo/scripts/data-upstream.sha256") ||
    { echo "error: $checkouts: the upstream files above are missing or differ from scripts/data-upstream.sha256" >&2; exit 1; }
  # The converter takes every Strecha photo of a scene: none beyond the manifest.
  extra=$(extra_files "$checkouts" "$repo/scripts/data-upstream.sha256" '*.jpg' \
    $(awk '{print $2}' "$repo/scripts/data-upstream.sha256" | grep '^SfM_quality_evaluation/' | xargs -n1 dirname | sort -u))
  if [ -n "$extra" ]; then
    echo "$extra" | sed "s|^|not in scripts/data-upstream.sha256: $checkouts/|" >&2
    echo "error: $checkouts: files the conversion would take are not in the manifest" >&2
    exit 1
  fi
  echo "converting into $to"
  mkdir -p "$to"
  touch "$to/$upstream_mark"
  python=/usr/bin/python3; [ -x "$python" ] || python=python3
  "$python" "$repo/scripts/convert_upstream.py" "$checkouts" "$to"
  verify "$to"
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
verify "$src" strict
# Only the manifest's files are copied (nothing else from the source lands in the data folder).
mkdir -p "$to"
rm -f "$to/$upstream_mark"  # every file is now the reference's
while read -r _ rel; do
  mkdir -p "$to/$(dirname "$rel")"
  cp -p "$src/$rel" "$to/$rel"
done < "$manifest"
verify "$to"
report
