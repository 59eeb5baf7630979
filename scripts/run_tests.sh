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
# Two passes: everything not timed against the wall clock on every core (pytest-xdist,
# PYTEST_WORKERS to override), then the `serial` tests (a node fed over DDS in real time) alone,
# so that no other test competes with them for the CPU. Exit status 5 (nothing selected, e.g.
# a path given on the command line holds no serial test) counts as success.
run() {
  local rc=0
  python -m pytest -q -p no:cacheprovider "$@" || rc=$?
  if [ "$rc" -ne 0 ] && [ "$rc" -ne 5 ]; then exit "$rc"; fi
}
run -n "${PYTEST_WORKERS:-auto}" -m "not serial" "$@"
run -m serial "$@"
