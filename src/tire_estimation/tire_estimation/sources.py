"""Recorded and simulated streams as one sequence of typed samples for the pipeline.

The bag reader and the simulator produce whole-stream arrays (:mod:`tire_estimation.sim.streams`,
checked as a whole there; the bag reader drops and counts the input messages the node's checks
refuse, :attr:`~tire_estimation.bag.reader.BagData.dropped`), or blocks of them in stamp order
(:mod:`tire_estimation.bag.stream`: the samples of the blocks one after the other are those of
the whole bag); these functions turn them into the
typed samples of :mod:`tire_estimation.core.samples`, merged in the pipeline's ``(stamp,
priority)`` order, so that the replay and the campaigns feed
:class:`~tire_estimation.core.pipeline.EstimationPipeline` the way the node does.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any

import numpy as np

from tire_estimation.core.samples import (
    GnssFix,
    GnssVelocity,
    ImuSample,
    MeasuredVelocity,
    Sample,
    Steering,
    TireForces,
    WheelSpeeds,
    merge,
)
from tire_estimation.sim.streams import (
    GnssStream,
    GnssVelocityStream,
    ImuStream,
    SpeedStream,
    SteeringStream,
    TireForceStream,
    WheelSpeedStream,
)

if TYPE_CHECKING:
    from tire_estimation.bag.reader import BagData
    from tire_estimation.sim.streams import SimResult


def _wheel_speeds(s: WheelSpeedStream) -> Iterator[Sample]:
    values = s.wheel_speed_rad_s
    for k, t in enumerate(s.t_ns.tolist()):
        yield WheelSpeeds(t, values[k])


def _steering(s: SteeringStream) -> Iterator[Sample]:
    for t, a in zip(s.t_ns.tolist(), s.angle_rad.tolist(), strict=True):
        yield Steering(t, a)


def _imu(s: ImuStream) -> Iterator[Sample]:
    gyro, acc = s.angular_velocity_rad_s, s.linear_acceleration_m_s2
    for k, t in enumerate(s.t_ns.tolist()):
        yield ImuSample(t, gyro[k], acc[k])


def _fixes(s: GnssStream) -> Iterator[Sample]:
    cov = s.position_covariance_m2
    lat, lon, alt = s.lat_deg.tolist(), s.lon_deg.tolist(), s.alt_m.tolist()
    for k, t in enumerate(s.t_ns.tolist()):
        yield GnssFix(t, lat[k], lon[k], alt[k], cov[k])


def _unknown_if_zero(cov: np.ndarray) -> np.ndarray | None:
    return cov if cov.any() else None


def _velocities(s: GnssVelocityStream) -> Iterator[Sample]:
    # every row, a bad one too: the radius estimator drops and counts it
    vel, cov = s.velocity_enu_m_s, s.covariance_m2_s2
    for k, t in enumerate(s.t_ns.tolist()):
        yield GnssVelocity(t, vel[k], _unknown_if_zero(cov[k]))


def velocity_stream(gnss: GnssStream) -> GnssVelocityStream | None:
    """The Doppler velocity a :class:`GnssStream` carries beside its fixes, or None. Its rows
    of NaN velocity are fixes without a velocity (left out); a covariance is passed on as it is
    (all zero or absent: not given)."""
    if gnss.velocity_enu_m_s is None:
        return None
    keep = np.isfinite(gnss.velocity_enu_m_s).all(axis=1)
    cov = gnss.velocity_covariance_m2_s2
    cov = np.zeros((gnss.t_ns.size, 3, 3)) if cov is None else cov
    return GnssVelocityStream(gnss.t_ns[keep], gnss.velocity_enu_m_s[keep], cov[keep])


def _tire_forces(s: TireForceStream) -> Iterator[Sample]:
    for k, t in enumerate(s.t_ns.tolist()):
        yield TireForces(t, s.fx_n[k], s.fy_n[k], s.fz_n[k], s.valid[k])


def _measured_velocity(s: SpeedStream) -> Iterator[Sample]:
    for t, v in zip(s.t_ns.tolist(), s.vx_m_s.tolist(), strict=True):
        yield MeasuredVelocity(t, v)


def stream_samples(
    *,
    wheel_speeds: WheelSpeedStream | None = None,
    steering: SteeringStream | None = None,
    imu: ImuStream | None = None,
    gnss: GnssStream | None = None,
    gnss_velocity: GnssVelocityStream | None = None,
    tire_forces: TireForceStream | None = None,
    velocity: SpeedStream | None = None,
) -> Iterator[Sample]:
    """Every sample of the given streams, merged in the pipeline's order (lazy).

    Without ``gnss_velocity`` the Doppler velocity that ``gnss`` carries is used."""
    if gnss is not None and gnss_velocity is None:
        gnss_velocity = velocity_stream(gnss)
    streams: tuple[tuple[Any, Callable[[Any], Iterator[Sample]]], ...] = (
        (wheel_speeds, _wheel_speeds),
        (steering, _steering),
        (imu, _imu),
        (gnss, _fixes),
        (gnss_velocity, _velocities),
        (tire_forces, _tire_forces),
        (velocity, _measured_velocity),
    )
    return merge([samples(s) for s, samples in streams if s is not None])


def sample_count(*streams: object) -> int:
    """Number of samples of the given streams (None entries count 0)."""
    return sum(int(s.t_ns.size) for s in streams if s is not None)  # type: ignore[attr-defined]


def bag_samples(bag: BagData, radius_only: bool = False) -> Iterator[Sample]:
    """The input samples of a bag. The measured velocity is used only when the bag has no wheel
    speeds (a vehicle without them, such as the Revs export); ``radius_only`` leaves out what
    the radius MPF does not use (tyre forces, measured velocity)."""
    has_wheels = bag.wheel_speeds is not None and bag.wheel_speeds.t_ns.size > 0
    return stream_samples(
        wheel_speeds=bag.wheel_speeds,
        steering=bag.steering,
        imu=bag.imu,
        gnss=bag.gnss,
        gnss_velocity=bag.gnss_velocity,
        tire_forces=None if radius_only else bag.tire_forces,
        velocity=None if has_wheels or radius_only else bag.vehicle_velocity,
    )


def sim_samples(sim: SimResult, tire_forces: bool = True) -> Iterator[Sample]:
    """The sensor samples of a simulated drive."""
    return stream_samples(
        wheel_speeds=sim.wheel_speeds,
        steering=sim.steering,
        imu=sim.imu,
        gnss=sim.gnss,
        tire_forces=sim.tire_forces if tire_forces else None,
    )
