#!/usr/bin/env bash
# linecloud as another project's library: installs the built tree into a
# prefix, then builds and runs tests/consumer (find_package(linecloud),
# linecloud::core; it localizes one synthetic query) against it, and again
# with linecloud as a subdirectory (add_subdirectory: libraries only).
# Expects ./build configured and built (scripts/run.sh test or demo).
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
cmake --build build/consumer/subdirectory -j2
./build/consumer/subdirectory/consumer
# The pkg-config file names the installed core library.
PKG_CONFIG_PATH="$prefix/lib/pkgconfig" pkg-config --modversion linecloud
