#!/usr/bin/env bash
# clang-format over the C++ sources (.clang-format). With --check: lists the
# files that differ and exits non-zero, and checks the layers (scripts/check_layers.py);
# otherwise rewrites them in place.
# Generated files (solvers/p6l_template.h) are left as their generator writes them.
set -euo pipefail
cd "$(dirname "$0")/.."
mapfile -t files < <(git ls-files '*.cc' '*.h' | grep -v '^src/linecloud/solvers/p6l_template.h$')
if [ "${1:-}" = "--check" ]; then
  bad=()
  for f in "${files[@]}"; do
    clang-format --dry-run -Werror "$f" >/dev/null 2>&1 || bad+=("$f")
  done
  if [ ${#bad[@]} -gt 0 ]; then
    echo "error: not formatted (run bash scripts/format.sh): ${bad[*]}" >&2
    exit 1
  fi
  echo "format: ${#files[@]} files formatted as .clang-format says"
  python3 scripts/check_layers.py && echo "layers: no upward include (scripts/check_layers.py)"
else
  clang-format -i "${files[@]}"
fi
