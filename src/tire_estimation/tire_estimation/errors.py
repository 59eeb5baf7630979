"""All exceptions raised by tire_estimation.

Every error the package raises derives from :class:`TireEstimationError`, so a caller can catch
the package's errors without catching programming errors. Messages name the offending field or
input and its value.
"""

from __future__ import annotations

import reprlib

#: longest repr of a value in a message (a 4 MB list would otherwise become a 4 MB line)
MAX_VALUE_REPR = 80

_REPR = reprlib.Repr()
_REPR.maxstring = MAX_VALUE_REPR
_REPR.maxother = MAX_VALUE_REPR
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = 6
_REPR.maxlevel = 3


def short_repr(value: object) -> str:
    """``repr(value)`` of at most about :data:`MAX_VALUE_REPR` characters (``...`` marks a cut)."""
    if isinstance(value, int) and value.bit_length() > 100:  # repr fails beyond 4300 digits
        return f"<integer of about {len(format(value, 'x')) * 1.2:.0f} digits>"
    try:
        text = _REPR.repr(value)
    except Exception:  # a value whose __repr__ fails
        text = f"<{type(value).__name__}>"
    if len(text) > MAX_VALUE_REPR:
        text = text[: MAX_VALUE_REPR - 3] + "..."
    return text


def one_line(text: str, limit: int = 300) -> str:
    """``text`` on one line (runs of whitespace, newlines included, become one space), cut to
    at most ``limit`` characters."""
    flat = " ".join(str(text).split())
    return flat if len(flat) <= limit else flat[: limit - 3] + "..."


class TireEstimationError(Exception):
    """Base class of every error raised by tire_estimation."""


class ConfigError(TireEstimationError, ValueError):
    """A configuration field has a missing, malformed or out-of-range value."""

    def __init__(self, field: str, value: object, reason: str) -> None:
        self.field = field
        self.value = value
        self.reason = reason
        super().__init__(f"{field}={short_repr(value)}: {reason}")

    def __reduce__(self) -> tuple[type, tuple[object, ...]]:
        # rebuilt from the constructor's arguments, so that the error crosses a process
        # boundary (a Dask or process-pool worker) as itself
        return type(self), (self.field, self.value, self.reason)


class VehicleConfigError(ConfigError):
    """The vehicle description (vehicle.yaml or bag metadata) is missing or absurd."""


class InputError(TireEstimationError, ValueError):
    """A measurement sample cannot be used (NaN, wrong shape, out of order, unknown name, ...).

    ``kind`` is a short stable identifier used as a counter key on ``/diagnostics``.
    """

    def __init__(self, kind: str, message: str) -> None:
        self.kind = kind
        super().__init__(message)

    def __reduce__(self) -> tuple[type, tuple[object, ...]]:
        return type(self), (self.kind, str(self))


class BagError(TireEstimationError):
    """A bag cannot be read or written, or lacks the topics a command needs."""


class ScenarioError(TireEstimationError, ValueError):
    """An unknown simulation scenario or an invalid scenario option."""


class StateFileError(TireEstimationError, ValueError):
    """A persistence file cannot be read safely: too large, nested too deep, not UTF-8 JSON,
    non-finite or absurdly large numbers, duplicate keys."""
