#!/usr/bin/env bash
# Prints the folder of the real data sets, by the rule of docs/data.md (also in
# src/linecloud/testing/data_dir.h, python/tests/conftest.py, web/tests/console.test.mjs):
#   $LINECLOUD_DATA when set; else ../shared/data beside the checkout where it exists;
#   else data/ in the checkout (where scripts/get_data.sh puts the sets).
set -euo pipefail
repo="$(cd "$(dirname "$0")/.." && pwd)"
if [ -n "${LINECLOUD_DATA:-}" ]; then
  echo "$LINECLOUD_DATA"
elif [ -d "$repo/../shared/data" ]; then
  (cd "$repo/../shared/data" && pwd)
else
  echo "$repo/data"
fi
