#!/usr/bin/env bash
# Fetches HYLC's fitted sheet energies (the `hylcmaterials/*.json` of github.com/PhoenixDigitalFX/ARCSim-HYLC,
# pinned commit below) for the macro check of the knit crate (`crates/knit/examples/macro_check.rs`,
# docs/BENCHMARKS.md, "Knit: the cell check with the generator's constants (issue 45)").
#
# They are not vendored: ARCSim-HYLC is distributed under ARCSim's licence (UC Regents, 2013), which allows
# use "for educational, research, and not-for-profit purposes" only and asks that its text accompany every
# copy. Cite: Sperl, Narain, Wojtan, "Homogenized Yarn-Level Cloth", ACM TOG 39(4), SIGGRAPH 2020; and, as
# that licence requires, Narain, Samii, O'Brien, "Adaptive Anisotropic Remeshing for Cloth Simulation",
# ACM TOG 31(6) 2012, and Narain, Pfaff, O'Brien, "Folding and Crumpling Adaptive Sheets", ACM TOG 32(4) 2013.
#
# Usage: tools/fetch_hylc_materials.sh [DEST]   (default DEST: target/hylc_materials)
set -euo pipefail
commit=7bfd2cfb44163c182866b8e43ef3cdb1154bbfff
dest=${1:-target/hylc_materials}
mkdir -p "$dest"
for name in stock1 rib1 LICENSE; do
  case $name in LICENSE) path=LICENSE; out=LICENSE-ARCSim.txt ;; *) path=hylcmaterials/$name.json; out=$name.json ;; esac
  curl -fsSL "https://raw.githubusercontent.com/PhoenixDigitalFX/ARCSim-HYLC/$commit/$path" -o "$dest/$out"
done
echo "wrote $dest: stock1.json rib1.json LICENSE-ARCSim.txt"
