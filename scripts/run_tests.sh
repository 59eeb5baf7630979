#!/usr/bin/env bash
# The whole test suite: lint, then pytest over tests/. Expects env.sh to be sourced (make test).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
echo "== ruff"
ruff check .
ruff format --check .
echo "== pytest"
# ROS-dependent tests must run here, not skip: a missing rclpy or message build is a failure.
export TIRE_ESTIMATION_REQUIRE_ROS=1
# an isolated DDS domain per run, so parallel runs on one machine do not see each other
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( (RANDOM % 100) + 1 ))}"
exec python -m pytest -q -p no:cacheprovider "$@"
