"""Small validators for frozen configuration dataclasses.

Each raises :class:`~tire_estimation.errors.ConfigError` (or the subclass passed as ``error``)
naming the field and its value.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from tire_estimation.errors import ConfigError


def require_finite(field: str, value: float, error: type[ConfigError] = ConfigError) -> None:
    """Raise unless ``value`` is a finite real number."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise error(field, value, "must be a number")
    if not math.isfinite(value):
        raise error(field, value, "must be finite")


def require_positive(field: str, value: float, error: type[ConfigError] = ConfigError) -> None:
    """Raise unless ``value`` is finite and > 0."""
    require_finite(field, value, error)
    if value <= 0:
        raise error(field, value, "must be > 0")


def require_non_negative(field: str, value: float, error: type[ConfigError] = ConfigError) -> None:
    """Raise unless ``value`` is finite and >= 0."""
    require_finite(field, value, error)
    if value < 0:
        raise error(field, value, "must be >= 0")


def require_range(
    field: str,
    value: float,
    low: float,
    high: float,
    error: type[ConfigError] = ConfigError,
) -> None:
    """Raise unless ``low <= value <= high``."""
    require_finite(field, value, error)
    if not low <= value <= high:
        raise error(field, value, f"must be within [{low}, {high}]")


def require_int_range(
    field: str, value: int, low: int, high: int, error: type[ConfigError] = ConfigError
) -> None:
    """Raise unless ``value`` is an int with ``low <= value <= high``."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise error(field, value, "must be an integer")
    if not low <= value <= high:
        raise error(field, value, f"must be within [{low}, {high}]")


def require_choice(
    field: str, value: object, choices: Iterable[str], error: type[ConfigError] = ConfigError
) -> None:
    """Raise unless ``value`` is one of ``choices`` (the message lists them as a tuple)."""
    allowed = tuple(choices)
    if value not in allowed:
        raise error(field, value, f"must be one of {allowed}")
