"""Pieces both nodes share: parameter descriptors from specs, persistence, and the process
around a node (spin until Ctrl-C or SIGTERM, then its lifecycle shutdown)."""

from __future__ import annotations

import json
import re
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import (
    InvalidParameterValueException,
    ParameterException,
    ParameterUninitializedException,
)
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions

from tire_estimation.core.validation import unknown_key_reason
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError, TireEstimationError, one_line
from tire_estimation.params import ParameterSpec
from tire_estimation.persistence import Identity, delete_state, restore, save_state

#: the vehicle name a node has when neither a vehicle file nor ``vehicle.name`` gives one
DEFAULT_VEHICLE_NAME = VehicleParams().name
#: what /diagnostics says when a node does not persist for want of a vehicle identity
NO_IDENTITY_NOTE = (
    f"persistence off: no vehicle identity (set vehicle_file or a vehicle.name other than "
    f"{DEFAULT_VEHICLE_NAME!r})"
)


def parameter_descriptor(spec: ParameterSpec) -> ParameterDescriptor:
    """Read-only descriptor with unit, description, choices and range of a dataclass field."""
    text = f"[{spec.unit}] {spec.doc}" if spec.unit else spec.doc
    if spec.choices:
        text = f"{text} One of: {', '.join(spec.choices)}."
    desc = ParameterDescriptor(description=text, read_only=True)
    if spec.range is not None and spec.kind is float:
        desc.floating_point_range = [
            FloatingPointRange(from_value=spec.range[0], to_value=spec.range[1], step=0.0)
        ]
    elif spec.range is not None and spec.kind is int:
        desc.integer_range = [
            IntegerRange(from_value=int(spec.range[0]), to_value=int(spec.range[1]), step=1)
        ]
    if spec.default is None:  # optional: unset unless given (any type accepted)
        desc.dynamic_typing = True
    return desc


def declare_specs(node: Node, specs: Sequence[ParameterSpec]) -> None:
    """Declare one parameter per spec, with its default and descriptor.

    A value outside the descriptor's range raises :class:`ConfigError` naming the parameter and
    the allowed values (rclpy refuses it before the configuration is built).
    """
    for spec in specs:
        # an empty list has no ROS type: declare a list of names by its type (unset until given)
        value = (
            Parameter.Type.STRING_ARRAY if spec.kind is list and not spec.default else spec.default
        )
        try:
            node.declare_parameter(spec.name, value, parameter_descriptor(spec))
        except InvalidParameterValueException as exc:
            # rclpy's message: "Invalid parameter value (VALUE) for parameter. Reason: ..."
            found = re.search(r"value \((.*)\) for parameter", str(exc.args[0]))
            value = found.group(1) if found else exc.args[0]
            raise ConfigError(spec.name, value, f"must be {spec.summary()}") from exc


def parameter_values(node: Node, specs: Sequence[ParameterSpec]) -> dict[str, Any]:
    """The values of the declared parameters of ``specs`` that are set, by name (a list of
    names declared empty and never given is left out: its default applies)."""
    out: dict[str, Any] = {}
    for spec in specs:
        if node.has_parameter(spec.name):
            try:
                value = node.get_parameter(spec.name).value
            except ParameterUninitializedException:
                continue
            if value is None and spec.kind is list:
                continue  # given as [] (no ROS type): the default, an empty list
            out[spec.name] = value
    return out


def reject_undeclared_overrides(node: Node) -> None:
    """Raise :class:`ConfigError` for the first parameter given to ``node`` (``-p name:=value``,
    ``--params-file``, the constructor's ``parameter_overrides``) that it did not declare,
    naming the nearest declared one: rclpy ignores such a value silently, so a misspelled
    ``radius.n_particle`` would leave the default in place. Call it after the declarations."""
    declared = list(node.list_parameters([], 0).names)
    for name, param in node._parameter_overrides.items():  # rclpy has no public accessor
        if not node.has_parameter(name):
            reason = unknown_key_reason(name, declared, what="parameter")
            raise ConfigError(name, param.value, reason)


#: how soon the spin loop sees a stop signal, s (a signal never interrupts a callback)
STOP_POLL_PERIOD_S = 0.1


class StopSignals:
    """SIGINT (Ctrl-C) and SIGTERM as a request to stop, while the context is entered: the
    handler only sets :attr:`requested`, so a signal never lands inside a callback and ROS
    is still up for the node's shutdown transition (rclpy's own handlers shut the context
    down first). The previous handlers come back on exit."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.requested = False
        self._previous: dict[int, Any] = {}

    def __enter__(self) -> StopSignals:
        if threading.current_thread() is threading.main_thread():
            for sig in self.SIGNALS:
                self._previous[sig] = signal.signal(sig, self._on_signal)
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)

    def _on_signal(self, signum: int, frame: Any) -> None:
        self.requested = True


def make_executor(context: Any) -> Executor:
    """The executor a node spins in: rclpy's C++ ``EventsExecutor`` (a fraction of the
    per-message overhead of the Python executors), the ``SingleThreadedExecutor`` when this
    rclpy has none."""
    try:
        from rclpy.experimental import EventsExecutor
    except ImportError:
        return SingleThreadedExecutor(context=context)
    return EventsExecutor(context=context)


def spin_until_stopped(node: Node, stop: StopSignals) -> None:
    """Run the node's callbacks (:func:`make_executor`) until a stop signal or the end of its
    context."""
    executor = make_executor(node.context)
    executor.add_node(node)
    try:
        while not stop.requested and node.context.ok():
            executor.spin_once(timeout_sec=STOP_POLL_PERIOD_S)
    finally:
        executor.remove_node(node)
        executor.shutdown()


def spin_node(name: str, factory: Callable[[], Any], args: list[str] | None = None) -> None:
    """Create the node, spin it until Ctrl-C or SIGTERM, run its lifecycle shutdown (which
    saves its state) and shut down ROS: exit status 0.

    A configuration error (bad or unknown parameter, unreadable parameters file) ends the
    process with one line on stderr naming the parameter and exit status 2. The node must
    have ``finish()`` (:class:`tire_estimation.nodes.lifecycle.ManagedNode`).
    """
    node: Any = None
    with StopSignals() as stop:
        try:
            rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
            node = factory()
            spin_until_stopped(node, stop)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        except (TireEstimationError, ParameterException, _rclpy.RCLError) as exc:
            print(one_line(f"{name}: configuration error: {exc}"), file=sys.stderr)
            raise SystemExit(2) from exc
        finally:
            if node is not None:
                node.finish()
                node.destroy_node()
            if rclpy.ok():
                rclpy.shutdown()


def restore_state(
    node: Node, path: Path | None, identity: Identity, target: Any, what: str
) -> str:
    """Restore saved state into ``target.load_state_dict`` if it belongs to ``identity``
    (:func:`tire_estimation.persistence.restore`: stale temporary files removed, the file read
    with bounds, every value checked); a rejected file or part is logged as a warning.

    Returns the note shown on /diagnostics (what was restored, or why not).
    """
    if path is None:
        return "persistence disabled"
    outcome = restore(path, identity, target, what)
    if outcome.removed_temps:
        node.get_logger().info(
            f"removed {outcome.removed_temps} temporary file(s) of {path} left by a killed save"
        )
    if outcome.rejected:
        node.get_logger().warning(f"saved {what} not restored as saved: {outcome.note}")
    return outcome.note


def save_state_of(
    node: Node, path: Path | None, identity: Identity, target: Any, what: str
) -> bool:
    """Write ``target.state_dict()``; on failure log a warning and return False."""
    if path is None:
        return True
    try:
        save_state(path, identity, target.state_dict())
    except OSError as exc:
        node.get_logger().warning(f"could not save the {what}: {exc}")
        return False
    return True


def explicit_identity(vehicle_file: str, vehicle_name: str) -> bool:
    """A vehicle file or a vehicle name other than the default says whose state a node holds;
    without one a node does not persist (vehicles left at the defaults would share a file)."""
    return bool(vehicle_file) or vehicle_name != DEFAULT_VEHICLE_NAME


def state_text(target: Any) -> str:
    """``target.state_dict()`` as canonical JSON: a save is due only when it changed since the
    state was restored, saved or reset (a node never writes a prior it has not changed)."""
    return json.dumps(target.state_dict(), sort_keys=True, default=str)


class NodeState:
    """A node's saved state (``target.state_dict()``) in ``persistence_file``: restored at
    construction, written only when it changed since it was restored, saved or reset.

    ``path_text`` empty, or no ``explicit`` vehicle identity (:func:`explicit_identity`):
    persistence off, ``path`` None and ``note`` says why. ``what`` names the state in the log.
    """

    def __init__(
        self,
        node: Node,
        path_text: str,
        identity: Identity,
        explicit: bool,
        target: Any,
        what: str,
    ) -> None:
        self.path: Path | None = Path(path_text).expanduser() if path_text else None
        self.identity = identity
        self.target = target
        self.what = what
        self._node = node
        #: what /diagnostics says: what was restored, or why not
        self.note = "persistence disabled"
        if self.path is not None and not explicit:
            self.path, self.note = None, NO_IDENTITY_NOTE
        if self.path is not None:
            self.note = restore_state(node, self.path, identity, target, what)
        #: the state as last restored, saved or reset: a save writes only a change
        self.saved_text = state_text(target) if self.path is not None else ""

    def changed(self) -> bool:
        """The state differs from the one last restored, saved or reset."""
        return state_text(self.target) != self.saved_text

    def save(self) -> bool:
        """Write the state when it changed; False when the write failed (logged)."""
        if self.path is None:
            return True
        text = state_text(self.target)
        if text == self.saved_text:
            return True
        if not save_state_of(self._node, self.path, self.identity, self.target, self.what):
            return False
        self.saved_text = text
        return True

    def save_on_shutdown(self) -> bool:
        """:meth:`save`, logging why nothing is written."""
        if self.path is None:
            self._node.get_logger().info(f"{self.what} not saved: {self.note}")
        elif not self.changed():
            self._node.get_logger().info(
                f"{self.what} unchanged since restored, saved or reset: {self.path} not written"
            )
        return self.save()

    def reset(self) -> None:
        """Delete the file: the state went back to its prior."""
        if self.path is not None:
            delete_state(self.path)
            self.saved_text = state_text(self.target)
