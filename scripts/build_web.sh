#!/usr/bin/env bash
# The console of `linecloud serve`: npm packages pinned by web/package-lock.json
# (three.js; playwright-core for its browser test), copied with the page into
# build/web, where `linecloud serve` finds it beside the executable (and
# `cmake --install` puts it in share/linecloud/web). Offline afterwards.
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
echo "console: $out ($(du -sh "$out" | cut -f1))"
