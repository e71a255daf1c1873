"""The layers of docs/architecture.md: a library source includes only its own folder and the
folders before it in LAYERS (tests may include anything). Prints each upward include; exit 1
when there is one not in KNOWN."""

import re
import sys
from pathlib import Path

LAYERS = ["util", "geometry", "solvers", "estimation", "lifting", "io", "features", "localize",
          "pipeline", "synthetic", "privacy", "draw", "colmap", "mapping", "benchmarks", "eval", "serve",
          "apps", "python", "testing"]
# Known upward includes, each a debt named in docs/architecture.md.
KNOWN = {("privacy/audit.cc", "draw")}

root = Path(__file__).resolve().parents[1] / "src" / "linecloud"
rank = {name: k for k, name in enumerate(LAYERS)}
bad = []
for path in sorted(root.glob("*/*")):
    folder = path.parent.name
    if path.suffix not in (".h", ".cc") or path.stem.endswith("_test") or folder not in rank:
        continue
    for target in re.findall(r'#include "linecloud/(\w+)/', path.read_text()):
        if target in rank and rank[target] > rank[folder]:
            where = f"{folder}/{path.name}"
            if (where, target) not in KNOWN:
                bad.append(f"{where} includes {target}/ (a later layer)")
folders = {p.name for p in root.iterdir() if p.is_dir()}
bad += [f"{f}/ is not in scripts/check_layers.py's LAYERS" for f in sorted(folders - set(rank))]
for line in bad:
    print("error: " + line, file=sys.stderr)
sys.exit(1 if bad else 0)
