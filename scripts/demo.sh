#!/usr/bin/env bash
# Install gsr_cad and reconstruct a bundled sample curve; the result lands in out/demo-curve.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/venv.sh "cad"
.venv/bin/gsr curve samples/curves/bspline_07.csv -o out/demo-curve --seed 1 \
  --truth samples/curves/bspline_07.truth.csv
echo "wrote out/demo-curve (result.json, control_points.csv, report.png)"
