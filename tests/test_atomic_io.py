"""Crash-safe writes: temp file in the same directory, fsync of the file and the directory,
rename; stale temporary files removed; one helper used by every report and state writer."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tire_estimation import atomic_io
from tire_estimation.atomic_io import (
    atomic_write_json,
    atomic_write_text,
    remove_stale_temps,
    temp_pattern,
)

PACKAGE = Path(atomic_io.__file__).resolve().parent


def _dead_pid() -> int:
    """The id of a process that has ended."""
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_write_fsyncs_the_file_and_the_directory_then_renames(tmp_path, monkeypatch) -> None:
    path = tmp_path / "sub" / "metrics.json"
    synced: list[str] = []
    real_fsync = os.fsync

    def fsync(fd: int) -> None:
        synced.append(os.readlink(f"/proc/self/fd/{fd}"))
        real_fsync(fd)

    monkeypatch.setattr(atomic_io.os, "fsync", fsync)
    atomic_write_json(path, {"a": 1.5, "b": [1, 2]})
    assert json.loads(path.read_text()) == {"a": 1.5, "b": [1, 2]}
    # the temporary file (same directory, unique name) before the rename, then the directory
    assert len(synced) == 2
    assert re.fullmatch(rf"\.metrics\.json\.{os.getpid()}\.[0-9a-f]+\.tmp", Path(synced[0]).name)
    assert Path(synced[0]).parent == path.parent
    assert Path(synced[1]) == path.parent
    assert sorted(p.name for p in path.parent.iterdir()) == ["metrics.json"]


def test_a_failed_write_keeps_the_old_content_and_leaves_no_temp(tmp_path, monkeypatch) -> None:
    path = tmp_path / "state.json"
    atomic_write_text(path, "old")

    def broken_replace(src: str, dst: str) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(atomic_io.os, "replace", broken_replace)
    with pytest.raises(OSError, match="disk full"):
        atomic_write_text(path, "new")
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["state.json"]


def test_stale_temps_of_dead_writers_and_old_versions_are_removed(tmp_path) -> None:
    path = tmp_path / "radii.json"
    path.write_text("{}")
    dead = tmp_path / f".radii.json.{_dead_pid()}.0a1b2c.tmp"
    mine = tmp_path / f".radii.json.{os.getpid()}.ffff.tmp"
    legacy = tmp_path / "radii.jsonab_cd123.tmp"  # tempfile.mkstemp(prefix=name)
    legacy_dot = tmp_path / ".radiiq2w3e4r5.tmp"  # tempfile.mkstemp(prefix=".stem")
    alive = tmp_path / f".radii.json.{os.getppid()}.beef.tmp"  # a running writer
    others = [tmp_path / "other.json.tmp", tmp_path / ".other.json.1.ab.tmp", tmp_path / "x.tmp"]
    for p in (dead, mine, legacy, legacy_dot, alive, *others):
        p.write_text("partial")
    removed = remove_stale_temps(path)
    assert sorted(removed) == sorted([dead, mine, legacy, legacy_dot])
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["radii.json", alive.name, *(p.name for p in others)]
    )
    # a write cleans up before it writes
    dead.write_text("partial")
    atomic_write_text(path, "{}")
    assert not dead.exists() and alive.exists()
    assert remove_stale_temps(tmp_path / "missing_dir" / "x.json") == []


def test_temp_pattern_matches_only_the_temps_of_its_file() -> None:
    pattern = temp_pattern(Path("/d/metrics.json"))
    assert pattern.fullmatch(".metrics.json.123.abc.tmp")
    assert pattern.fullmatch(".metricsabcdefgh.tmp")
    assert not pattern.fullmatch(".metrics.json.123.abc.tmp.x")
    assert not pattern.fullmatch(".metrics2.json.123.abc.tmp")
    assert not pattern.fullmatch("metrics.json")


def test_report_and_state_writers_use_the_atomic_helper() -> None:
    """No report or state file of the replay, the command line or the evaluation is written
    in place (a crash would leave half a file)."""
    files = [PACKAGE / "replay.py", PACKAGE / "cli.py", PACKAGE / "persistence.py"]
    files += sorted((PACKAGE / "evaluation").rglob("*.py"))
    in_place = re.compile(r"\.write_text\(|\.write_bytes\(|json\.dump\(|\.open\(\s*[\"']w")
    offenders = [
        f"{f.relative_to(PACKAGE)}:{n}"
        for f in files
        for n, line in enumerate(f.read_text().splitlines(), 1)
        if in_place.search(line)
    ]
    assert offenders == []
