"""All exceptions raised by tire_estimation.

Every error the package raises derives from :class:`TireEstimationError`, so a caller can catch
the package's errors without catching programming errors. Messages name the offending field or
input and its value.
"""

from __future__ import annotations


class TireEstimationError(Exception):
    """Base class of every error raised by tire_estimation."""


class ConfigError(TireEstimationError, ValueError):
    """A configuration field has a missing, malformed or out-of-range value."""

    def __init__(self, field: str, value: object, reason: str) -> None:
        self.field = field
        self.value = value
        self.reason = reason
        super().__init__(f"{field}={value!r}: {reason}")


class VehicleConfigError(ConfigError):
    """The vehicle description (vehicle.yaml or bag metadata) is missing or absurd."""


class InputError(TireEstimationError, ValueError):
    """A measurement sample cannot be used (NaN, wrong shape, out of order, unknown name, ...).

    ``kind`` is a short stable identifier used as a counter key on ``/diagnostics``.
    """

    def __init__(self, kind: str, message: str) -> None:
        self.kind = kind
        super().__init__(message)


class BagError(TireEstimationError):
    """A bag cannot be read or written, or lacks the topics a command needs."""


class ScenarioError(TireEstimationError, ValueError):
    """An unknown simulation scenario or an invalid scenario option."""


class StateFileError(TireEstimationError, ValueError):
    """A persistence file cannot be read safely: too large, nested too deep, not UTF-8 JSON,
    non-finite or absurdly large numbers, duplicate keys."""
