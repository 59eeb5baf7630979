"""Persist learned estimates across restarts (JSON file, atomic writes, identity check).

The file holds the identity the estimates belong to (vehicle name and tire-set id) and the
estimator's ``state_dict()``. :func:`load_state` returns the state only when the identity matches,
so a tire change (new tire-set id) or another vehicle starts from the prior.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tire_estimation.errors import TireEstimationError

FORMAT_VERSION = 1


@dataclass(frozen=True)
class Identity:
    """Who the learned estimates belong to."""

    vehicle_name: str
    tire_set_id: str


def _finite_json(obj: Any) -> Any:
    """Replace non-finite floats by None so the file is strict JSON."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {str(k): _finite_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite_json(v) for v in obj]
    if hasattr(obj, "tolist"):
        return _finite_json(obj.tolist())
    return obj


def save_state(path: str | Path, identity: Identity, state: dict[str, Any]) -> None:
    """Write ``state`` for ``identity`` to ``path`` atomically (temp file + rename)."""
    path = Path(path).expanduser()
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {
        "format_version": FORMAT_VERSION,
        "vehicle_name": identity.vehicle_name,
        "tire_set_id": identity.tire_set_id,
        "saved_unix_s": time.time(),
        "state": _finite_json(state),
    }
    fd, tmp = tempfile.mkstemp(prefix=path.name, suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            json.dump(payload, fh, indent=1)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def load_state(path: str | Path, identity: Identity) -> tuple[dict[str, Any] | None, str]:
    """Return ``(state, reason)``; ``state`` is None when absent, unreadable or not ours."""
    path = Path(path).expanduser()
    if not path.is_file():
        return None, f"no saved estimates at {path}"
    try:
        payload = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        return None, f"unreadable saved estimates {path}: {exc}"
    if not isinstance(payload, dict) or payload.get("format_version") != FORMAT_VERSION:
        return None, f"saved estimates {path} have an unknown format"
    if payload.get("vehicle_name") != identity.vehicle_name:
        return None, f"saved estimates are for vehicle {payload.get('vehicle_name')!r}"
    if payload.get("tire_set_id") != identity.tire_set_id:
        return None, f"saved estimates are for tire set {payload.get('tire_set_id')!r}"
    state = payload.get("state")
    if not isinstance(state, dict):
        return None, f"saved estimates {path} hold no state"
    return state, f"restored estimates from {path}"


def delete_state(path: str | Path) -> None:
    """Remove the saved estimates (reset)."""
    Path(path).expanduser().unlink(missing_ok=True)


class LearnedState:
    """Several estimators' ``state_dict`` in one persistence file, one key each.

    ``parts`` maps a key (``"radius"``, ``"stiffness"``) to an object with ``state_dict()`` and
    ``load_state_dict(d)``, or to None when that estimator is not running (its saved part is
    then kept untouched in :attr:`pending` and written back, so a restart without it does not
    lose it). :meth:`load_state_dict` restores each part on its own: a rejected part leaves the
    others restored, and :attr:`notes` says what happened to each.

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

    def load_state_dict(self, state: dict[str, Any]) -> None:
        if self.legacy_key in self.parts and "rear" in state:
            state = {self.legacy_key: state}
        self.notes = {}
        for key, saved in state.items():
            part = self.parts.get(key)
            if part is None:
                self.pending[key] = saved
                self.notes[key] = "kept (estimator not running)"
                continue
            try:
                part.load_state_dict(saved)
            except (TireEstimationError, KeyError, TypeError, ValueError, AttributeError) as exc:
                self.notes[key] = f"rejected: {exc}"
            else:
                self.notes[key] = "restored"
        for key in self.parts:
            self.notes.setdefault(key, "not in the file")

    def summary(self) -> str:
        """``radius restored, stiffness rejected: ...`` (for /diagnostics)."""
        return ", ".join(f"{k} {v}" for k, v in self.notes.items())
