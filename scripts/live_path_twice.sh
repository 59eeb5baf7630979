#!/usr/bin/env bash
# The README's live path on the bundled bag, run twice: both nodes, the bag played with /clock,
# Ctrl-C; prints each run's deflation alarm lines and the nodes' exit codes. The two runs must
# print the same alarm (nothing persists between them).
#   usage: bash scripts/live_path_twice.sh [RATE]   (RATE: bag_player speed-up, default 2)
set -uo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
# shellcheck disable=SC1091
source env.sh
RATE="${1:-2}"
LOGS="$(mktemp -d)"
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( (RANDOM % 100) + 1 ))}"
V=bags/ece_r64_6min/vehicle.yaml
for run in 1 2; do
  estimator_node --ros-args -p vehicle_file:=$V -p use_sim_time:=true \
    -p "persistence_file:=''" > "$LOGS/estimator_$run.log" 2>&1 &
  est=$!
  detector_node --ros-args -p vehicle_file:=$V -p use_sim_time:=true -p "persistence_file:=''" \
    -p detector.calibration_time_s:=150.0 -p detector.calibration_average_s:=60.0 \
    > "$LOGS/detector_$run.log" 2>&1 &
  det=$!
  sleep 3
  bag_player bags/ece_r64_6min --rate "$RATE" > "$LOGS/player_$run.log" 2>&1
  sleep 2
  kill -INT "$est" "$det"
  wait "$est"; est_rc=$?
  wait "$det"; det_rc=$?
  echo "run $run: estimator exit $est_rc, detector exit $det_rc"
  grep -o "tyre deflation alarm.*" "$LOGS/detector_$run.log" | sed "s/^/run $run: /"
done
echo "logs: $LOGS"
