"""The managed-node lifecycle both nodes share (configure, activate, deactivate, cleanup,
shutdown), and the start that configures and activates a node by itself (``autostart``)."""

from __future__ import annotations

import traceback
from collections import Counter
from typing import Any

from rclpy.exceptions import ParameterException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.lifecycle import LifecycleNode, LifecyclePublisher, LifecycleState
from rclpy.lifecycle import TransitionCallbackReturn as Return
from rclpy.publisher import Publisher
from rclpy.service import Service
from rclpy.subscription import Subscription
from rclpy.timer import Timer

from tire_estimation.errors import InputError, TireEstimationError, one_line

#: the primary states from which the shutdown transition runs
_LIVE_STATES = ("unconfigured", "inactive", "active")
#: what a message's handling raises on bad input: dropped and counted, never raised
BAD_INPUT = (TireEstimationError, ValueError, TypeError, AttributeError)


class ManagedNode(LifecycleNode):
    """A lifecycle node whose configure step builds everything from its (read-only)
    parameters.

    The subclass declares its parameters in its constructor and ends it with :meth:`start`;
    it implements :meth:`_configure` (configuration, state, publishers made with
    ``create_lifecycle_publisher``, subscriptions, services, timers) and
    :meth:`save_on_shutdown`. Its input callbacks process a message only while
    :attr:`active` (:meth:`accept`; bad input: :meth:`drop`). Deactivate, cleanup and
    shutdown save the state; cleanup and shutdown destroy what configure made.
    """

    #: messages per input stream (made by ``_configure``)
    received: Counter[str]
    #: dropped messages and samples per ``stream:reason`` (made by ``_configure``)
    dropped: Counter[str]

    def __init__(self, node_name: str, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        #: inputs are processed only while active
        self.active = False
        self.configured = False
        #: why the last configure failed (None: it did not)
        self.configure_error: Exception | None = None
        self._autostarting = False
        self._own_entities: set[int] = set()

    # --- start and stop ---------------------------------------------------------------------
    def start(self) -> None:
        """End of the constructor: with ``autostart`` configure and activate, raising what
        made configure fail; without it wait, unconfigured, for a lifecycle manager."""
        self._own_entities = {id(e) for e in self._entities()}
        if not self.get_parameter("autostart").value:
            self.get_logger().info(f"{self.get_name()} unconfigured: waiting for configure")
            return
        self._autostarting = True
        try:
            outcome = self.trigger_configure()
        finally:
            self._autostarting = False
        if outcome != Return.SUCCESS:
            raise self.configure_error or RuntimeError(f"{self.get_name()}: configure failed")
        self.trigger_activate()

    def state_label(self) -> str:
        """The primary state: unconfigured, inactive, active or finalized."""
        return str(self._state_machine.current_state[1])  # rclpy has no public accessor

    def finish(self) -> None:
        """The shutdown transition (it saves) from whatever state the node is in; when the
        transition cannot run (ROS already shut down), save directly."""
        if self.state_label() in _LIVE_STATES:
            try:
                self.trigger_shutdown()
                return
            except _rclpy.RCLError:
                pass
        if self.configured:
            self.save_on_shutdown()

    # --- inputs -----------------------------------------------------------------------------
    def accept(self, stream: str) -> bool:
        """Count a message of ``stream``; True when it is to be processed (the node is active),
        else it is dropped as ``stream:inactive``."""
        self.received[stream] += 1
        if not self.active:
            self.dropped[f"{stream}:inactive"] += 1
        return self.active

    def drop(self, stream: str, exc: Exception) -> None:
        """Count a message whose handling raised :data:`BAD_INPUT` as ``stream:kind`` (an
        :class:`InputError`) or ``stream:invalid`` (anything else, logged, throttled)."""
        if isinstance(exc, InputError):
            self.dropped[f"{stream}:{exc.kind}"] += 1
            return
        self.dropped[f"{stream}:invalid"] += 1
        self.get_logger().warning(f"dropped a {stream} message: {exc}", throttle_duration_sec=5.0)

    # --- to implement -----------------------------------------------------------------------
    def _configure(self) -> None:
        raise NotImplementedError

    def save_on_shutdown(self) -> None:
        raise NotImplementedError

    # --- transitions ------------------------------------------------------------------------
    def on_configure(self, state: LifecycleState) -> Return:
        self.configure_error = None
        try:
            self._configure()
        except Exception as exc:  # a failed configure leaves the node unconfigured
            self.configure_error = exc
            self._destroy_configured()
            if not self._autostarting:  # with autostart the constructor raises it
                if isinstance(exc, (TireEstimationError, ParameterException)):
                    self.get_logger().error(one_line(f"configure failed: {exc}"))
                else:
                    self.get_logger().error(f"configure failed:\n{traceback.format_exc()}")
            return Return.FAILURE
        self.configured = True
        return super().on_configure(state)

    def on_activate(self, state: LifecycleState) -> Return:
        self.active = True
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> Return:
        self.active = False
        self.save_on_shutdown()
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> Return:
        self.save_on_shutdown()
        self._destroy_configured()
        return super().on_cleanup(state)

    def on_shutdown(self, state: LifecycleState) -> Return:
        self.active = False
        if self.configured:
            self.save_on_shutdown()
        self._destroy_configured()
        return super().on_shutdown(state)

    def on_error(self, state: LifecycleState) -> Return:
        self.active = False
        self._destroy_configured()
        return Return.SUCCESS

    # --- what configure made ----------------------------------------------------------------
    def _entities(self) -> list[Any]:
        return [*self.publishers, *self.subscriptions, *self.services, *self.timers]

    def _destroy_configured(self) -> None:
        """Destroy the publishers, subscriptions, services and timers made since :meth:`start`
        (the node's parameter and lifecycle services stay)."""
        for entity in self._entities():
            if id(entity) in self._own_entities:
                continue
            if isinstance(entity, LifecyclePublisher):
                self.destroy_lifecycle_publisher(entity)
            elif isinstance(entity, Publisher):
                self.destroy_publisher(entity)
            elif isinstance(entity, Subscription):
                self.destroy_subscription(entity)
            elif isinstance(entity, Service):
                self.destroy_service(entity)
            elif isinstance(entity, Timer):
                self.destroy_timer(entity)
        self.configured = False
