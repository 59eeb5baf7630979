"""Persist learned estimates across restarts: one JSON file, written atomically and durably,
read back with bounds, restored only when it belongs to this vehicle and tire set.

The file holds the identity the estimates belong to (vehicle name and tire-set id) and the
estimator's ``state_dict()``. Reading it is bounded (:func:`read_json`: file size, nesting
depth, digits of an integer, magnitude of a float; no NaN or Infinity, no duplicate keys), so a
corrupt or hostile file is reported, never a crash. :func:`restore` is what the nodes do at
start: remove the temporary files a killed writer left, read the file, check the identity, and
hand the state to the estimator, whose ``load_state_dict`` checks every value
(:mod:`tire_estimation.core.state_checks`); a rejected state leaves the estimator at its prior.
"""

from __future__ import annotations

import json
import math
import re
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tire_estimation.atomic_io import atomic_write_text, remove_stale_temps
from tire_estimation.errors import StateFileError, TireEstimationError

FORMAT_VERSION = 1
#: Largest persistence file read, bytes (a saved state is a few kB).
MAX_FILE_BYTES = 1 << 20
#: Deepest nesting of arrays and objects read (a saved state: file, state, part, axle, matrix,
#: row = 6).
MAX_DEPTH = 16
#: Most digits of an integer read (an int64 time stamp in ns has 19).
MAX_INT_DIGITS = 20
#: Largest magnitude of a number read or written; a larger one is no learned value (the
#: largest: a stiffness variance, (3e7 N/rad)^2 ~ 1e15). Written as null.
MAX_ABS_NUMBER = 1e30
#: What a restore may raise on a malformed state besides the package's errors.
RESTORE_ERRORS: tuple[type[Exception], ...] = (
    TireEstimationError,
    LookupError,
    TypeError,
    ValueError,
    ArithmeticError,
    AttributeError,
)
_FILE_KEYS = ("format_version", "vehicle_name", "tire_set_id", "saved_unix_s", "state")
#: a JSON string (with its escapes; an unterminated one runs to the end) or a bracket: one
#: pass over the text, each character read once
_TOKEN = re.compile(r'"(?:[^"\\]|\\.)*"?|[\[\]{}]')


@dataclass(frozen=True)
class Identity:
    """Who the learned estimates belong to."""

    vehicle_name: str
    tire_set_id: str


@dataclass(frozen=True)
class RestoreOutcome:
    """What :func:`restore` did.

    Attributes:
        note: one line for /diagnostics and the log: what was restored, or why not.
        rejected: the file or a part of it was rejected (corrupt, implausible), as opposed to
            absent or belonging to another vehicle or tire set.
        removed_temps: temporary files of killed writers removed before reading.
    """

    note: str
    rejected: bool
    removed_temps: int = 0


def _finite_json(obj: Any) -> Any:
    """Replace non-finite and absurdly large floats by None so the file is strict JSON that
    :func:`read_json` reads back (a rejected value then rejects its part, not the file)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) and abs(obj) <= MAX_ABS_NUMBER else None
    if isinstance(obj, dict):
        return {str(k): _finite_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite_json(v) for v in obj]
    if hasattr(obj, "tolist"):
        return _finite_json(obj.tolist())
    return obj


def _parse_int(text: str) -> int:
    digits = len(text.lstrip("-"))
    if digits > MAX_INT_DIGITS:
        raise StateFileError(f"an integer has {digits} digits (at most {MAX_INT_DIGITS})")
    return int(text)


def _parse_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value) or abs(value) > MAX_ABS_NUMBER:
        raise StateFileError(f"number {text[:40]} is outside +-{MAX_ABS_NUMBER:g}")
    return value


def _parse_constant(text: str) -> float:
    raise StateFileError(f"non-finite number {text}")


def _object(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise StateFileError(f"duplicate key {key[:40]!r}")
        out[key] = value
    return out


def nesting_depth(text: str, limit: int = MAX_DEPTH) -> int:
    """Deepest nesting of arrays and objects in JSON ``text`` (brackets inside strings do not
    count), counted up to ``limit + 1``; linear in the length of ``text``."""
    depth = deepest = 0
    for token in _TOKEN.finditer(text):
        first = token.group()[0]
        if first == '"':
            continue
        depth += 1 if first in "[{" else -1
        if depth > deepest:
            deepest = depth
            if deepest > limit:
                break
    return deepest


def read_json(path: str | Path, max_bytes: int = MAX_FILE_BYTES) -> Any:
    """The JSON value in ``path``, read with bounds; raises :class:`StateFileError` (or
    ``OSError``) naming what is wrong: larger than ``max_bytes``, not UTF-8, empty, nested
    deeper than :data:`MAX_DEPTH`, an integer longer than :data:`MAX_INT_DIGITS` digits, a
    number beyond :data:`MAX_ABS_NUMBER`, NaN or Infinity, a duplicate key, not JSON."""
    with Path(path).open("rb") as fh:
        data = fh.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise StateFileError(f"larger than {max_bytes} bytes")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise StateFileError(f"not UTF-8 text ({exc.reason} at byte {exc.start})") from exc
    if not text.strip():
        raise StateFileError("empty")
    if nesting_depth(text) > MAX_DEPTH:
        raise StateFileError(f"nested deeper than {MAX_DEPTH} levels")
    try:
        return json.loads(
            text,
            parse_int=_parse_int,
            parse_float=_parse_float,
            parse_constant=_parse_constant,
            object_pairs_hook=_object,
        )
    except StateFileError:
        raise
    except (ValueError, RecursionError) as exc:
        raise StateFileError(f"not JSON: {exc}") from exc


def save_state(path: str | Path, identity: Identity, state: dict[str, Any]) -> None:
    """Write ``state`` for ``identity`` to ``path`` atomically and durably
    (:func:`~tire_estimation.atomic_io.atomic_write_text`)."""
    payload = {
        "format_version": FORMAT_VERSION,
        "vehicle_name": identity.vehicle_name,
        "tire_set_id": identity.tire_set_id,
        "saved_unix_s": time.time(),
        "state": _finite_json(state),
    }
    atomic_write_text(Path(path).expanduser(), json.dumps(payload, indent=1, allow_nan=False))


def _load(
    path: Path, identity: Identity, what: str = "estimates"
) -> tuple[dict[str, Any] | None, str, bool]:
    """``(state, reason, rejected)``: the state when the file is ours and well-formed."""
    if not path.is_file():
        return None, f"no saved {what} at {path}", False
    try:
        payload = read_json(path)
    except (OSError, StateFileError) as exc:
        return None, f"rejected: unreadable saved {what} {path}: {exc}", True
    if not isinstance(payload, dict):
        return None, f"rejected: saved {what} {path} are not an object", True
    unknown = sorted(k for k in payload if k not in _FILE_KEYS)
    missing = [k for k in _FILE_KEYS if k not in payload and k != "saved_unix_s"]
    version = payload.get("format_version")
    if unknown or missing or isinstance(version, bool) or version != FORMAT_VERSION:
        why = (
            f"unknown keys {unknown}"
            if unknown
            else f"missing {missing}"
            if missing
            else f"format_version {version!r}, expected {FORMAT_VERSION}"
        )
        return None, f"rejected: saved {what} {path} have an unknown format: {why}", True
    vehicle, tire_set = payload["vehicle_name"], payload["tire_set_id"]
    if not isinstance(vehicle, str) or not isinstance(tire_set, str):
        return None, f"rejected: saved {what} {path} have no valid identity", True
    if vehicle != identity.vehicle_name:
        return None, f"saved {what} are for vehicle {vehicle[:80]!r}", False
    if tire_set != identity.tire_set_id:
        return None, f"saved {what} are for tire set {tire_set[:80]!r}", False
    state = payload["state"]
    if not isinstance(state, dict):
        return None, f"rejected: saved {what} {path} hold no state", True
    return state, f"saved {what} found in {path}", False


def load_state(path: str | Path, identity: Identity) -> tuple[dict[str, Any] | None, str]:
    """Return ``(state, reason)``; ``state`` is None when absent, unreadable, malformed or
    not ours (``reason`` starts with ``rejected:`` for an unreadable or malformed file)."""
    state, reason, _ = _load(Path(path).expanduser(), identity)
    return state, reason


def restore(path: str | Path, identity: Identity, target: Any, what: str) -> RestoreOutcome:
    """Restore the state saved in ``path`` into ``target.load_state_dict`` if it belongs to
    ``identity``; never raises on a bad file or state.

    First removes the temporary files killed writers of ``path`` left. A ``target`` with
    ``summary()`` (:class:`LearnedState`) reports per part; any other target is restored
    whole or rejected whole (it must leave itself unchanged when it raises).
    """
    path = Path(path).expanduser()
    removed = len(remove_stale_temps(path))
    state, reason, rejected = _load(path, identity, what)
    if state is None:
        return RestoreOutcome(reason, rejected, removed)
    try:
        target.load_state_dict(state)
    except RESTORE_ERRORS as exc:
        note = f"rejected: saved {what} in {path}: {exc}"
        return RestoreOutcome(note, True, removed)
    summary = getattr(target, "summary", None)
    if summary is None:
        return RestoreOutcome(f"restored {what} from {path}", False, removed)
    notes = target.notes
    parts_rejected = any(n.startswith("rejected") for n in notes.values())
    return RestoreOutcome(f"{what} from {path}: {summary()}", parts_rejected, removed)


def delete_state(path: str | Path) -> None:
    """Remove the saved estimates (reset) and any temporary files of it."""
    path = Path(path).expanduser()
    path.unlink(missing_ok=True)
    remove_stale_temps(path)


class LearnedState:
    """Several estimators' ``state_dict`` in one persistence file, one key each.

    ``parts`` maps a key (``"radius"``, ``"stiffness"``) to an object with ``state_dict()`` and
    ``load_state_dict(d)``, or to None when that estimator is not running (its saved part is
    then kept untouched in :attr:`pending` and written back, so a restart without it does not
    lose it). :meth:`load_state_dict` restores each part on its own: a rejected part (malformed,
    implausible, or a key that names no part) leaves the others restored, and :attr:`notes` says
    what happened to each.

    A file written before the parts existed holds the radius estimator's state at the top level
    (key ``rear``); it is read as the ``legacy_key`` part.
    """

    def __init__(self, parts: dict[str, Any], legacy_key: str = "radius") -> None:
        self.parts = parts
        self.legacy_key = legacy_key
        self.pending: dict[str, Any] = {}
        self.notes: dict[str, str] = {}

    def state_dict(self) -> dict[str, Any]:
        out = dict(self.pending)
        for key, part in self.parts.items():
            if part is not None:
                out[key] = part.state_dict()
        return out

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        if self.legacy_key in self.parts and "rear" in state:
            state = {self.legacy_key: state}
        self.notes = {}
        for key, saved in state.items():
            if key not in self.parts:
                self.notes[str(key)[:40]] = "rejected: unknown part"
                continue
            part = self.parts[key]
            if part is None:
                self.pending[key] = saved
                self.notes[key] = "kept (estimator not running)"
                continue
            if not isinstance(saved, Mapping):
                self.notes[key] = f"rejected: not an object but {type(saved).__name__}"
                continue
            try:
                part.load_state_dict(saved)
            except RESTORE_ERRORS as exc:
                self.notes[key] = f"rejected: {exc}"
            else:
                self.notes[key] = "restored"
        for key in self.parts:
            self.notes.setdefault(key, "not in the file")

    def summary(self) -> str:
        """``radius restored, stiffness rejected: ...`` (for /diagnostics)."""
        return ", ".join(f"{k} {v}" for k, v in self.notes.items())
