#!/usr/bin/env bash
# linecloud as another project's library: installs the built tree into a
# prefix, then builds and runs tests/consumer (find_package(linecloud),
# linecloud::core; it localizes one synthetic query) against it, and again
# with linecloud as a subdirectory (add_subdirectory: libraries only).
# Expects ./build configured and built (scripts/run.sh test or demo).
#   --subdirectory-configure-only   configure the subdirectory variant without compiling the
#                                   library's sources a second time (CI: the same sources as ./build)
set -euo pipefail
cd "$(dirname "$0")/.."
prefix="$PWD/build/consumer/prefix"
rm -rf build/consumer
cmake --install build --prefix "$prefix" >/dev/null
echo "installed: $(cd "$prefix" && find . -name 'linecloudConfig*.cmake' -o -name '*.pc' -o -name 'lib*.a' | sort | tr '\n' ' ')"
cmake -S tests/consumer -B build/consumer/installed -G Ninja -DCMAKE_PREFIX_PATH="$prefix" >/dev/null
cmake --build build/consumer/installed
./build/consumer/installed/consumer
cmake -S tests/consumer -B build/consumer/subdirectory -G Ninja -DLINECLOUD_SOURCE_DIR="$PWD" >/dev/null
if [ "${1:-}" = "--subdirectory-configure-only" ]; then
  echo "subdirectory: configured (not compiled: --subdirectory-configure-only)"
else
  cmake --build build/consumer/subdirectory -j2
  ./build/consumer/subdirectory/consumer
fi
# The README's Localizer example (tests/consumer/photos.cc): a map loaded once,
# photos from memory and from features. On the shared model's photo (a fixed
# key, a throwaway key store; its heavily compressed photos give no pose), and
# when CI's evaluation left its fountain-P11 work, on a group's held-out photos
# against that group's map (each must be localized).
keys="$PWD/build/consumer/keys"
key="$PWD/build/consumer/fixed.key"
(umask 077; printf 'directions sphere\n%s\n' "$(printf '3c%.0s' $(seq 32))" > "$key")
data="$(bash scripts/data_dir.sh)"
maupertuis="$data/colmap-maupertuis"
if [ -d "$maupertuis" ]; then
  LINECLOUD_KEY_STORE="$keys" ./build/linecloud lift --model "$maupertuis/reconstruction" \
    --database "$maupertuis/colmap.db" --key-file "$key" --out build/consumer/maupertuis.lcm >/dev/null
  ./build/consumer/installed/photos build/consumer/maupertuis.lcm \
    "SIMPLE_PINHOLE 1919 1079 1847.53 959.5 539.5" "$maupertuis/images/00.jpg"
else
  echo "real data absent: $maupertuis (the photo example skipped)"
fi
work=build/eval/fountain-P11
if [ -f "$work/prepared.json" ] && [ -f "$work/lifting.key" ]; then
  LINECLOUD_KEY_STORE="$keys" ./build/linecloud lift --model "$work/groups/g00/map" \
    --database "$work/colmap/database.db" --key-file "$work/lifting.key" \
    --out build/consumer/fountain-g00.lcm >/dev/null
  ./build/consumer/installed/photos --expect-success build/consumer/fountain-g00.lcm \
    "PINHOLE 1536 1024 1379.74 1382.08 760.095 503.155" \
    "$data/strecha/fountain-P11/images/0000.jpg" "$data/strecha/fountain-P11/images/0001.jpg"
fi
# The pkg-config file names the installed core library.
PKG_CONFIG_PATH="$prefix/lib/pkgconfig" pkg-config --modversion linecloud
