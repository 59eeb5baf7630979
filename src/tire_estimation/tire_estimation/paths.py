"""Output locations of the commands, checked before any work starts.

A command that would write its result after minutes of computation checks first that it can:
the directory exists or can be created, it is a directory, a file can be created in it, and the
name is not too long. Each failure is a :class:`~tire_estimation.errors.ConfigError` naming the
option (``--out``) and the path, with the operating system's reason in one line.
"""

from __future__ import annotations

import argparse
import os
import uuid
from pathlib import Path

from tire_estimation.errors import ConfigError

#: the files ``tire-estimation replay`` writes in its ``--out``: removed when a run starts, so
#: that a run that fails or writes no metrics leaves no report of an earlier run looking current
REPLAY_REPORT_FILES = (
    "metrics.json",
    "radius_errors.png",
    "trajectory.png",
    "innovations.png",
    "detection.png",
    "lateral_state.png",
    "stiffness.png",
)


def out_argument(text: str) -> Path:
    """The value of an ``--out`` option: a path, not empty (an unset shell variable would
    otherwise make it the current directory)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("must not be empty")
    return Path(text)


def _reason(exc: OSError, doing: str) -> str:
    return f"{doing}: {exc.strerror or type(exc).__name__}"


def prepare_out_dir(path: Path, option: str = "--out") -> Path:
    """Create directory ``path`` (with its parents) and check a file can be written in it."""
    path = Path(path)
    try:
        if path.exists() and not path.is_dir():
            raise ConfigError(option, str(path), "is a file, not a directory")
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(option, str(path), _reason(exc, "cannot create the directory")) from exc
    probe = path / f".write-check-{uuid.uuid4().hex}"
    try:
        with probe.open("x"):
            pass
        probe.unlink()
    except OSError as exc:
        raise ConfigError(option, str(path), _reason(exc, "cannot write in it")) from exc
    return path


def check_new_path(path: Path, option: str = "--out", overwrite: bool = False) -> None:
    """``path`` (a file or directory written later) can be created: its name is valid, it does
    not exist unless ``overwrite``, it is not a directory when ``overwrite`` replaces files,
    and its parent directory exists (or is created) and is writable."""
    path = Path(path)
    try:
        exists = path.exists()
    except OSError as exc:  # a name too long
        raise ConfigError(option, str(path), _reason(exc, "not a usable path")) from exc
    if exists and not overwrite:
        raise ConfigError(option, str(path), "exists; pass --overwrite to replace it")
    try:
        prepare_out_dir(path.parent, option)
    except ConfigError as exc:
        raise ConfigError(option, str(path), f"its directory {exc.reason}") from exc
    if len(path.name.encode()) > _name_max(path.parent):
        raise ConfigError(option, str(path), "not a usable path: File name too long")


def _name_max(directory: Path) -> int:
    try:
        return int(os.pathconf(directory, "PC_NAME_MAX"))
    except (OSError, ValueError):
        return 255
