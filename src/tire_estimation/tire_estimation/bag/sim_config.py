"""``sim_config.yaml`` of a simulated bag: what the simulator did, checked key by key.

The file (written by :func:`tire_estimation.bag.writer.write_sim_bag`) holds the scenario, the
seed, the ENU origin, the duration, the events (pressure steps, ...) and the simulator's
configuration as a record. A key that is not one of these, an event without a time or kind, or
a value of the wrong type is an error naming it (``events[0].t_s``), so that a hand-edited file
is never half read.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from tire_estimation.core import yamlio
from tire_estimation.core.validation import reject_unknown_keys
from tire_estimation.errors import BagError, ConfigError
from tire_estimation.sim.streams import SimEvent

#: the top-level keys of sim_config.yaml
KEYS = ("scenario", "seed", "origin_lla", "duration_s", "events", "config")
#: the keys of one event
EVENT_KEYS = ("t_s", "kind", "detail")


def _number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _finite(field: str, value: object) -> float:
    if not _number(value):
        raise ConfigError(field, value, "must be a number")
    try:
        number = float(value)  # type: ignore[arg-type]
    except OverflowError:
        number = math.inf
    if not math.isfinite(number):
        raise ConfigError(field, value, "must be finite")
    return number


def parse_events(raw: object) -> tuple[SimEvent, ...]:
    """Events from the ``events`` list (None: no events); ConfigError naming a bad one."""
    if raw is None:
        return ()
    if not isinstance(raw, list):
        raise ConfigError("events", raw, "must be a list of {t_s, kind, detail}")
    events = []
    for i, item in enumerate(raw):
        name = f"events[{i}]"
        if not isinstance(item, Mapping):
            raise ConfigError(name, item, "must be a mapping {t_s, kind, detail}")
        reject_unknown_keys(item, EVENT_KEYS, prefix=f"{name}.")
        for key in ("t_s", "kind"):
            if key not in item:
                raise ConfigError(f"{name}.{key}", None, "missing")
        kind = item["kind"]
        if not isinstance(kind, str) or not kind:
            raise ConfigError(f"{name}.kind", kind, "must be a non-empty string")
        detail = item.get("detail")
        if detail is not None and not isinstance(detail, Mapping):
            raise ConfigError(f"{name}.detail", detail, "must be a mapping")
        events.append(SimEvent(_finite(f"{name}.t_s", item["t_s"]), kind, dict(detail or {})))
    return tuple(events)


def parse_sim_config(data: object) -> tuple[dict[str, Any], tuple[SimEvent, ...]]:
    """The checked content of sim_config.yaml (None: empty) and its events."""
    if data is None:
        return {}, ()
    if not isinstance(data, dict):
        raise ConfigError("sim_config", data, "must be a mapping")
    reject_unknown_keys(data, KEYS)
    scenario, seed = data.get("scenario"), data.get("seed")
    if scenario is not None and not isinstance(scenario, str):
        raise ConfigError("scenario", scenario, "must be a string")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int) or seed < 0):
        raise ConfigError("seed", seed, "must be a non-negative integer")
    origin = data.get("origin_lla")
    if origin is not None:
        if not isinstance(origin, list) or len(origin) != 3:
            raise ConfigError("origin_lla", origin, "must be a list [lat, lon, alt]")
        for i, v in enumerate(origin):
            _finite(f"origin_lla[{i}]", v)
    if data.get("duration_s") is not None:
        _finite("duration_s", data["duration_s"])
    if data.get("config") is not None and not isinstance(data["config"], Mapping):
        raise ConfigError("config", data["config"], "must be a mapping")
    return data, parse_events(data.get("events"))


def read_sim_config(path: Path) -> tuple[dict[str, Any], tuple[SimEvent, ...]]:
    """Load and check ``path``; BagError naming the file and what is wrong."""
    try:
        return parse_sim_config(yamlio.load_file(path, "sim_config.yaml"))
    except ConfigError as exc:
        text = str(exc) if exc.field == "sim_config.yaml" else f"{path}: {exc}"
        raise BagError(text) from exc


def events_from_text(text: str, source: str) -> tuple[SimEvent, ...]:
    """Events from YAML text (the bag metadata's copy); BagError naming ``source``."""
    try:
        return parse_events(yamlio.safe_load(text))
    except ConfigError as exc:
        raise BagError(f"{source}: {exc}") from exc
    except yaml.YAMLError as exc:
        raise BagError(f"{source}: not valid YAML: {yamlio.describe(exc)}") from exc
