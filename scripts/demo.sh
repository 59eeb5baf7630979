#!/usr/bin/env bash
# The demo (make demo): show what the bundled bag holds, replay it through the estimation
# pipeline (radius MPF with the AUG-KF baseline beside it, and the deflation detector) and print
# the learned radii against the truth and the deflation warning; plots and metrics.json land in
# the output directory. Expects env.sh to be sourced.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="${1:-$ROOT/out/demo}"
BAG="$ROOT/bags/ece_r64_6min"
mkdir -p "$OUT"
echo "== bundled bag: $BAG"
tire-estimation info "$BAG"
echo
echo "== replay through the estimators and the deflation detector (report in $OUT)"
echo "   (demo configuration scripts/demo_config.yaml: detector calibration shortened to 150 s)"
tire-estimation replay "$BAG" --out "$OUT" --config "$ROOT/scripts/demo_config.yaml"
echo
echo "plots: $(cd "$OUT" && ls ./*.png | tr '\n' ' ')"
