#!/usr/bin/env bash
# The pictures of docs/OUTPUTS.md: simulates the pants, renders the key page and the first tiles of the
# tiled PDF with pdftoppm, and the DXF-AAMA file with ezdxf's drawing add-on.
#
# Usage: tools/pattern_pictures.sh [OUT_DIR]   (default docs/outputs; run from the repository root)
# Needs: the skintight binary ($SKINTIGHT_BIN, default target/release/skintight), pdftoppm (Debian's
# poppler-utils), and a Python with ezdxf and matplotlib ($SKINTIGHT_PYTHON, default python3).
set -euo pipefail
out=${1:-docs/outputs}
bin=${SKINTIGHT_BIN:-target/release/skintight}
py=${SKINTIGHT_PYTHON:-python3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$bin" simulate examples/pants.json --out "$work/pants" --quiet > /dev/null
mkdir -p "$out"
# The key page and the first two tiles, at 40 dpi.
pdftoppm -r 40 -f 1 -l 3 -png "$work/pants/patterns-a4.pdf" "$out/pants-a4"
# The DXF as a pattern-CAD shows it.
"$py" - "$work/pants/patterns.dxf" "$out/pants-dxf.png" <<'PY'
import sys
import ezdxf
from ezdxf.addons.drawing import matplotlib as drawing

doc = ezdxf.readfile(sys.argv[1])
drawing.qsave(doc.modelspace(), sys.argv[2], dpi=100, bg="#FFFFFF")
PY
ls "$out"
