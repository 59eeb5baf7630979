"""Crash-safe writes of state and report files.

A file is written to a temporary file in the same directory (unique name
``.<name>.<pid>.<token>.tmp``), flushed and fsynced, renamed over the target with
:func:`os.replace`, and the directory is fsynced: after a crash or a power loss the target holds
either the previous or the new content, never a part. A process killed between the creation
and the rename leaves its temporary file behind; :func:`remove_stale_temps` removes those of
one target (the writers call it before every write, the nodes when they start).
"""

from __future__ import annotations

import errno
import json
import os
import re
import secrets
from pathlib import Path
from typing import Any

TEMP_SUFFIX = ".tmp"
#: temporary files of earlier writers (``tempfile.mkstemp`` with the target's name or
#: ``.<stem>`` as prefix: 8 random characters)
_LEGACY_RANDOM = r"[a-z0-9_]{8}"


def temp_pattern(path: Path) -> re.Pattern[str]:
    """Names of the temporary files of ``path``; group ``pid`` holds the writer's process id."""
    name, stem = re.escape(path.name), re.escape(path.stem)
    return re.compile(
        rf"(?:\.{name}\.(?P<pid>\d+)\.[0-9a-f]+|(?:{name}|\.{stem}){_LEGACY_RANDOM})"
        rf"{re.escape(TEMP_SUFFIX)}"
    )


def _alive(pid: int) -> bool:
    """Whether a process with id ``pid`` runs (and may still be writing)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except PermissionError:
        return True  # runs under another user
    except (ProcessLookupError, OverflowError):
        return False
    return True


def remove_stale_temps(path: str | Path) -> list[Path]:
    """Remove the temporary files ``path``'s writers left behind; return them.

    A temporary file of another running process (its pid in the name) is left alone.
    """
    path = Path(path).expanduser()
    pattern = temp_pattern(path)
    removed: list[Path] = []
    try:
        entries = list(path.parent.iterdir())
    except OSError:
        return removed
    me = os.getpid()
    for entry in entries:
        found = pattern.fullmatch(entry.name)
        if found is None:
            continue
        pid = found.group("pid")
        if pid is not None and int(pid) != me and _alive(int(pid)):
            continue
        try:
            entry.unlink()
        except OSError:  # gone meanwhile, or not ours to remove
            continue
        removed.append(entry)
    return removed


def fsync_directory(directory: Path) -> None:
    """Make a rename in ``directory`` durable (a no-op where directories cannot be fsynced)."""
    flags = os.O_RDONLY | getattr(os, "O_DIRECTORY", 0)
    try:
        fd = os.open(directory, flags)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError as exc:
        if exc.errno not in (errno.EINVAL, errno.ENOTSUP, errno.EBADF):
            raise
    finally:
        os.close(fd)


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Replace ``path`` by ``data`` atomically and durably (module docstring)."""
    path = Path(path).expanduser()
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temps(path)
    tmp = path.parent / f".{path.name}.{os.getpid()}.{secrets.token_hex(6)}{TEMP_SUFFIX}"
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    fsync_directory(path.parent)


def atomic_write_text(path: str | Path, text: str) -> None:
    """Replace ``path`` by ``text`` (UTF-8) atomically and durably."""
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(
    path: str | Path, obj: Any, *, indent: int | None = 2, allow_nan: bool = True
) -> None:
    """Replace ``path`` by ``obj`` as JSON (newline-terminated) atomically and durably."""
    atomic_write_text(path, json.dumps(obj, indent=indent, allow_nan=allow_nan) + "\n")
