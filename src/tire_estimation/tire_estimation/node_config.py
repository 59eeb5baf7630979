"""Node-level options of the estimator node (the estimator itself is configured by
:class:`~tire_estimation.core.radius.config.RadiusEstimatorConfig`, the vehicle by
:class:`~tire_estimation.core.vehicle.VehicleParams`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from tire_estimation.core.deflation.monitor import MonitorConfig
from tire_estimation.core.pipeline import PublishPeriods
from tire_estimation.core.validation import (
    Checked,
    Finite,
    NonNegative,
    Positive,
    one_of,
)
from tire_estimation.core.wheels import Names
from tire_estimation.errors import ConfigError

SENSOR_QOS = ("sensor_data", "reliable")


@dataclass(frozen=True)
class PersistentNodeOptions(Checked):
    """What every node that saves its state to a file takes: the vehicle, the tire set, the
    file and the lifecycle start (the subclasses document the fields and set the file's
    default)."""

    vehicle_file: str = ""
    tire_set_id: str = "default"
    persistence_file: str = ""
    persistence_period_s: Finite = 60.0
    autostart: bool = True

    def check(self) -> None:
        if not self.tire_set_id:
            raise ConfigError("tire_set_id", self.tire_set_id, "must not be empty")


@dataclass(frozen=True)
class EstimatorNodeOptions(PersistentNodeOptions):
    """ROS-side options of ``estimator_node``.

    Attributes:
        vehicle_file: path of a vehicle.yaml; empty = use the ``vehicle.*`` parameters.
        tire_set_id: identity of the mounted tire set; saved radii are restored only for the
            same vehicle name and tire set. Default ``default``.
        persistence_file: file the learned radii (and the learned stiffness, when the stiffness
            MPF runs) are saved to and restored from; empty = off.
            Default ``~/.ros/tire_estimation/learned_radii.json``.
        persistence_period_s: save period, s; <= 0 saves only on shutdown. Default 60.
        autostart: configure and activate the lifecycle node at start; false leaves it
            unconfigured for a lifecycle manager (``ros2 lifecycle set``). Default true.
        odometry_publish_period_s: minimum period between Odometry messages (header time), s;
            0 publishes after every wheel-speed sample. Default 0.02.
        radii_publish_period_s: minimum period between TireRadii messages (header time), s.
            Default 0.1.
        lateral_publish_period_s: minimum period between LateralState messages (header
            time), s. Default 0.02.
        tyre_force_enabled: run the tyre-force lateral Kalman filter when
            ``/vehicle/tire_forces`` messages arrive. Default true.
        stiffness_enabled: run the tyre-stiffness MPF (Berntorp & Di Cairano 2018) on the IMU,
            steering and wheel speeds (or ``/vehicle/velocity``); it publishes
            ``/tire_estimation/tire_stiffness`` and, while no tyre forces arrive,
            ``/tire_estimation/lateral_state``. Costs about 1-3 ms per IMU sample at 200
            particles. Default true.
        stiffness_publish_period_s: minimum period between TireStiffness messages (header
            time), s. Default 0.1.
        diagnostics_period_s: period of /diagnostics, s (wall or sim time). Default 1.
        sensor_qos: QoS of the sensor subscriptions, ``sensor_data`` (best effort, default) or
            ``reliable``.
        reorder_delay_s: samples are processed in header-stamp order when they arrive at most
            this long after the wheel speeds of a later stamp (so a live run computes what a
            replay of its recording computes); every output is delayed by as much, s.
            Default 0.05.
        max_clock_jump_s: a sample stamped more than this before or after the newest one is
            held; five agreeing ones make a new clock (a clock reset), an isolated one is
            dropped as ``<stream>:clock_jump``, s. Default 5.
        name_remaps: this robot's own joint and frame names for the contract's, as
            ``contract_name=own_name`` entries (``wheel_fl=front_left_wheel_joint``,
            ``front_wheel_angle=...``, ``base_link=base_footprint``, ``map=odom``); the wheel
            speeds, steering and tyre forces are read by these joint names, the outputs carry
            these frames and the wheel radii these joint names. Default empty: the contract's
            names.
    """

    persistence_file: str = "~/.ros/tire_estimation/learned_radii.json"
    odometry_publish_period_s: NonNegative = 0.02
    radii_publish_period_s: Positive = 0.1
    lateral_publish_period_s: NonNegative = 0.02
    tyre_force_enabled: bool = True
    stiffness_enabled: bool = True
    stiffness_publish_period_s: NonNegative = 0.1
    diagnostics_period_s: Positive = 1.0
    sensor_qos: Annotated[str, one_of(SENSOR_QOS)] = "sensor_data"
    reorder_delay_s: NonNegative = 0.05
    max_clock_jump_s: Positive = 5.0
    name_remaps: tuple[str, ...] = ()

    def check(self) -> None:
        super().check()
        Names.from_remaps(self.name_remaps)  # raises ConfigError naming name_remaps

    @property
    def names(self) -> Names:
        """The robot's joint and frame names."""
        return Names.from_remaps(self.name_remaps)


def periods_of(options: EstimatorNodeOptions) -> PublishPeriods:
    """The pipeline's output periods from the node options (as the node publishes)."""
    return PublishPeriods(
        odometry_s=options.odometry_publish_period_s,
        radii_s=options.radii_publish_period_s,
        lateral_s=options.lateral_publish_period_s,
        stiffness_s=options.stiffness_publish_period_s,
    )


@dataclass(frozen=True)
class DetectorNodeOptions(MonitorConfig, PersistentNodeOptions):
    """ROS-side options of ``detector_node``, the monitor's among them (the CUSUM itself:
    :class:`~tire_estimation.core.deflation.config.DeflationDetectorConfig`).

    Attributes:
        vehicle_file: path of a vehicle.yaml giving the vehicle name; empty = use
            ``vehicle.name``.
        tire_set_id: identity of the mounted tire set; the saved calibration is restored only
            for the same vehicle name and tire set. Default ``default``.
        persistence_file: file the calibration and alarms are saved to and restored from;
            empty = off. Default ``~/.ros/tire_estimation/deflation_detector.json``.
        persistence_period_s: save period, s; <= 0 saves only on events and shutdown.
            Default 60.
        autostart: configure and activate the lifecycle node at start; false leaves it
            unconfigured for a lifecycle manager (``ros2 lifecycle set``). Default true.
        diagnostics_period_s: period of /diagnostics, s. Default 1.
        braking_decel_m_s2: deceleration above which the car counts as braking, m/s^2.
            Default 1.
        braking_window_s: odometry span over which the deceleration is taken, s. Default 0.5.
        odometry_timeout_s: a speed older than this (against the radius stamp) is unknown, s.
            Default 1.
    """

    persistence_file: str = "~/.ros/tire_estimation/deflation_detector.json"
    diagnostics_period_s: Positive = 1.0


@dataclass(frozen=True)
class VehicleIdentity:
    """The vehicle's identity where a node needs no other vehicle data.

    Attributes:
        name: identity of the vehicle for persistence. Default ``vehicle``.
    """

    name: str = "vehicle"

    def __post_init__(self) -> None:
        if not self.name:
            raise ConfigError("name", self.name, "must not be empty")
