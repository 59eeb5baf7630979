#!/usr/bin/env bash
# The demo (make demo): replay a bundled bag through the estimator when the replay exists,
# otherwise simulate a short drive and show what the bag holds. Expects env.sh to be sourced.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="${1:-$ROOT/out/demo}"
mkdir -p "$OUT"
BAG="$ROOT/bags/ece_r64_short"
echo "== bundled bag: $BAG"
tire-estimation info "$BAG"
echo
echo "== simulating a fresh 2-minute city drive into $OUT/city_demo"
tire-estimation simulate city --minutes 2 --seed 7 --out "$OUT/city_demo" --overwrite
tire-estimation info "$OUT/city_demo"
