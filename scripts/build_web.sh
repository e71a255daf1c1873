#!/usr/bin/env bash
# The console of `linecloud serve`: npm packages pinned by web/package-lock.json
# (three.js; playwright-core for its browser test), copied with the page into
# build/web, where `linecloud serve` finds it beside the executable (and
# `cmake --install` puts it in share/linecloud/web), each text file with its
# gzip copy (NAME.gz). Offline afterwards.
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-build/web}"
(cd web && npm ci --no-audit --no-fund --loglevel=error)
rm -rf "$out"
mkdir -p "$out/vendor/three/addons/controls"
cp web/src/index.html web/src/app.js web/src/style.css "$out/"
cp web/node_modules/three/build/three.module.js web/node_modules/three/build/three.core.js \
   web/node_modules/three/LICENSE "$out/vendor/three/"
cp web/node_modules/three/examples/jsm/controls/OrbitControls.js "$out/vendor/three/addons/controls/"
# Compressed copies beside the files: the server sends NAME.gz to clients that take gzip.
find "$out" -type f \( -name '*.js' -o -name '*.css' -o -name '*.html' \) -exec gzip -9 -k -n -f {} \;
echo "console: $out ($(du -sh "$out" | cut -f1))"
