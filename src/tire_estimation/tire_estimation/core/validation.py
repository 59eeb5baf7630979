"""Small validators for frozen configuration dataclasses.

Each raises :class:`~tire_estimation.errors.ConfigError` (or the subclass passed as ``error``)
naming the field and its value.
"""

from __future__ import annotations

import difflib
import functools
import math
import typing
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, fields
from typing import Annotated, Any, ClassVar

from tire_estimation.errors import ConfigError


def require_finite(field: str, value: float, error: type[ConfigError] = ConfigError) -> None:
    """Raise unless ``value`` is a finite real number."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise error(field, value, "must be a number")
    if not math.isfinite(value):
        raise error(field, value, "must be finite")


def require_vector3(
    field: str, value: object, limit: float, error: type[ConfigError] = ConfigError, unit: str = ""
) -> None:
    """Raise unless ``value`` is a tuple of 3 finite numbers, each within +-``limit`` (in
    ``unit``); errors name ``field`` or the component ``field[i]``."""
    if not isinstance(value, tuple) or len(value) != 3:
        raise error(field, value, "must be 3 numbers [x, y, z]")
    for i, v in enumerate(value):
        require_finite(f"{field}[{i}]", v, error)
        if abs(v) > limit:
            raise error(f"{field}[{i}]", v, f"must be within +-{limit:g}{unit}")


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


@dataclass(frozen=True)
class Rule:
    """What a configuration field must hold; a field carries it in its annotation
    (``Annotated[float, in_range(0, 1)]`` or an alias such as :data:`Positive`).

    ``kind`` is ``bool``, ``finite``, ``positive`` (> 0), ``non_negative`` (>= 0), ``range``
    (a number in ``[low, high]``), ``int_range`` (an integer in ``[low, high]``) or ``choice``
    (one of ``choices``). The node's parameter descriptors and the generated parameter file
    read the same rules, so the range a user sees is the one that is checked.
    """

    kind: str
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] | None = None

    def check(self, field: str, value: Any, error: type[ConfigError] = ConfigError) -> None:
        """Raise ``error`` naming ``field`` and ``value`` unless ``value`` obeys the rule."""
        if self.kind == "finite":
            require_finite(field, value, error)
        elif self.kind == "bool":
            if not isinstance(value, bool):
                raise error(field, value, "must be a bool")
        elif self.kind == "positive":
            require_positive(field, value, error)
        elif self.kind == "non_negative":
            require_non_negative(field, value, error)
        elif self.kind == "range":
            require_range(field, value, float(self.low), float(self.high), error)  # type: ignore[arg-type]
        elif self.kind == "int_range":
            require_int_range(field, value, int(self.low), int(self.high), error)  # type: ignore[arg-type]
        elif self.kind == "choice":
            require_choice(field, value, self.choices or (), error)
        else:  # pragma: no cover - a rule built outside the constructors below
            raise ValueError(f"unknown rule kind {self.kind!r}")

    def text(self) -> str:
        """The rule as a user reads it: ``in [0, 1]``, ``> 0``, ``one of (a, b)``."""
        if self.kind == "finite":
            return "finite"
        if self.kind == "bool":
            return "true or false"
        if self.kind == "positive":
            return "> 0"
        if self.kind == "non_negative":
            return ">= 0"
        if self.kind in ("range", "int_range"):
            return f"in [{_number(self.low)}, {_number(self.high)}]"
        return "one of (" + ", ".join(self.choices or ()) + ")"


def _number(x: float | None) -> str:
    """A bound as a user writes it: 1000000, 0.05, 1e-06."""
    x = float(x)  # type: ignore[arg-type]
    return str(int(x)) if x.is_integer() and abs(x) < 1e9 else f"{x:g}"


BOOL = Rule("bool")
FINITE = Rule("finite")
POSITIVE = Rule("positive")
NON_NEGATIVE = Rule("non_negative")


#: Annotations of configuration fields that carry their rule (read by :func:`field_rules`).
Flag = Annotated[bool, BOOL]
Finite = Annotated[float, FINITE]
Positive = Annotated[float, POSITIVE]
NonNegative = Annotated[float, NON_NEGATIVE]


def in_range(low: float, high: float) -> Rule:
    """A number within ``[low, high]``."""
    return Rule("range", float(low), float(high))


#: A share, probability or ratio within [0, 1].
Fraction = Annotated[float, in_range(0.0, 1.0)]


def int_in_range(low: int, high: int) -> Rule:
    """An integer within ``[low, high]``."""
    return Rule("int_range", int(low), int(high))


def one_of(choices: Iterable[str]) -> Rule:
    """One of ``choices``."""
    return Rule("choice", choices=tuple(choices))


def known_names(name: object, valid: Iterable[str]) -> str:
    """``did you mean n_particles?`` (the valid name nearest ``name`` by
    :func:`difflib.get_close_matches`) or, with none near, ``known: a, b, c, d, e, ...``."""
    names = list(valid)
    near = difflib.get_close_matches(name, names, n=1) if isinstance(name, str) else []
    if near:
        return f"did you mean {near[0]}?"
    return f"known: {', '.join(names[:5])}{', ...' if len(names) > 5 else ''}"


def unknown_key_reason(
    key: object, valid: Iterable[str], prefix: str = "", what: str = "key"
) -> str:
    """Why ``key`` is rejected: ``unknown key; did you mean radius.n_particles?`` (the nearest
    valid key by :func:`difflib.get_close_matches`, written with ``prefix``) or, with none
    near, the first few valid keys."""
    names = sorted(valid)
    if not isinstance(key, str):
        return f"{what}s must be text, not {type(key).__name__}"
    near = difflib.get_close_matches(key, names, n=1, cutoff=0.6)
    if near:
        return f"unknown {what}; did you mean {prefix}{near[0]}?"
    shown = ", ".join(prefix + n for n in names[:5])
    return f"unknown {what}; valid: {shown}{', ...' if len(names) > 5 else ''}"


def reject_unknown_keys(
    data: Mapping[Any, Any],
    valid: Iterable[str],
    error: type[ConfigError] = ConfigError,
    prefix: str = "",
    what: str = "key",
) -> None:
    """Raise ``error`` naming ``prefix + key`` and the nearest valid key for the first key of
    ``data`` (in its order) that is not in ``valid``."""
    names = set(valid)
    for key in data:
        if key not in names:
            reason = unknown_key_reason(key, names, prefix, what)
            raise error(f"{prefix}{key}", data[key], reason)


def require_known_keys(
    cls: type,
    data: object,
    section: str,
    error: type[ConfigError] = ConfigError,
    prefix: str = "",
) -> Mapping[str, Any]:
    """``data`` if it is a mapping whose keys are all fields of dataclass ``cls``; else
    ``error`` naming ``section`` (not a mapping) or ``prefix`` + the first unknown key and the
    nearest field."""
    if not isinstance(data, Mapping):
        raise error(section, data, "must be a mapping")
    reject_unknown_keys(data, (f.name for f in fields(cls)), error, prefix)
    return data


def check_rules(
    config: object,
    rules: Mapping[str, Rule],
    error: type[ConfigError] = ConfigError,
    prefix: str = "",
) -> None:
    """Check every field of ``config`` named in ``rules`` (in the order of ``rules``); errors
    name the field as ``prefix + name``."""
    for name, rule in rules.items():
        rule.check(prefix + name, getattr(config, name), error)


@functools.cache
def field_rules(cls: type) -> dict[str, Rule]:
    """The rule each field of dataclass ``cls`` carries in its annotation, in field order
    (fields without one are left out; a subclass inherits its bases' fields and rules)."""
    hints = typing.get_type_hints(cls, include_extras=True)
    rules = {}
    for f in fields(cls):
        found = [m for m in getattr(hints.get(f.name), "__metadata__", ()) if isinstance(m, Rule)]
        if found:
            rules[f.name] = found[0]
    return rules


class Checked:
    """Base of the frozen configuration dataclasses: construction checks every field against
    the rule of its annotation (:func:`field_rules`), then :meth:`check`. Errors are ``ERROR``
    naming the field as ``PREFIX + name``."""

    ERROR: ClassVar[type[ConfigError]] = ConfigError
    PREFIX: ClassVar[str] = ""

    def __post_init__(self) -> None:
        check_rules(self, field_rules(type(self)), self.ERROR, self.PREFIX)
        self.check()

    def check(self) -> None:
        """Checks across fields, beyond each field's own rule (none here)."""
