#!/usr/bin/env bash
# Regenerate requirements/lock.txt: install requirements/direct.txt into a scratch venv and
# freeze it. Review the diff before committing.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
"${PYTHON:-python3.11}" -m venv "$tmp/venv"
"$tmp/venv/bin/python" -m pip install --quiet -r "$ROOT/requirements/direct.txt"
"$tmp/venv/bin/python" "$ROOT/scripts/freeze_lock.py" > "$ROOT/requirements/lock.txt"
echo "wrote requirements/lock.txt"
