"""Sensor models: sample a :class:`~tire_estimation.sim.dynamics.VehicleLog` into streams.

All functions are vectorized over the whole drive. Stamps are ``start_ns + k * period_ns``; the
state at a stamp is linearly interpolated from the integration grid (exact on grid points).
"""

from __future__ import annotations

import math

import numpy as np

from tire_estimation.core.arrays import F64, I64
from tire_estimation.core.geodesy import LocalTangentPlane
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.core.wheels import WHEEL_INDEX
from tire_estimation.sim.config import SensorConfig
from tire_estimation.sim.dynamics import GRAVITY_M_S2, VehicleLog
from tire_estimation.sim.streams import (
    GnssStream,
    ImuStream,
    SteeringStream,
    TireForceStream,
    TruthStream,
    WheelSpeedStream,
)


def _stamps(rate_hz: float, t_first_s: float, t_last_s: float) -> tuple[I64, F64]:
    """Integer-ns stamps k * period within [t_first, t_last] (relative), and the same in s."""
    period_ns = round(1e9 / rate_hz)
    k0 = math.ceil(t_first_s * 1e9 / period_ns - 1e-9)
    k1 = math.floor(t_last_s * 1e9 / period_ns + 1e-9)
    rel_ns = np.arange(max(k0, 0), k1 + 1, dtype=np.int64) * period_ns
    return rel_ns, rel_ns.astype(np.float64) * 1e-9


def _interp(log: VehicleLog, values: F64, t_s: F64) -> F64:
    """Linear interpolation of (n,) or (n, k) ``values`` on the log grid at ``t_s``."""
    if values.ndim == 1:
        return np.interp(t_s, log.t_s, values)
    return np.column_stack([np.interp(t_s, log.t_s, values[:, j]) for j in range(values.shape[1])])


def _bias_walk(
    rng: np.random.Generator, m: int, initial_std: float, walk_std_sqrt_s: float, period_s: float
) -> F64:
    """(m, 3) bias: N(0, initial_std^2) plus a random walk b_k+1 = b_k + walk sqrt(T) w_k."""
    b0 = rng.standard_normal(3) * initial_std
    steps = rng.standard_normal((m, 3)) * (walk_std_sqrt_s * math.sqrt(period_s))
    steps[0] = 0.0
    return b0[None, :] + np.cumsum(steps, axis=0)


def _gauss_markov(
    rng: np.random.Generator, m: int, sigma: float, tau_s: float, period_s: float
) -> F64:
    """Stationary first-order Gauss-Markov sequence with std ``sigma`` and time constant tau."""
    if sigma == 0.0 or m == 0:
        rng.standard_normal(m + 1)  # keep the stream of draws independent of sigma
        return np.zeros(m)
    phi = math.exp(-period_s / tau_s)
    x0 = rng.standard_normal() * sigma
    w = rng.standard_normal(m) * sigma * math.sqrt(1.0 - phi * phi)
    w[0] = 0.0
    # scipy.signal costs 0.6 s to import: only the simulator needs it, not the bag reader,
    # which imports this package for the stream types
    from scipy.signal import lfilter

    # x_k = phi x_{k-1} + sqrt(1 - phi^2) sigma w_k, x_0 ~ N(0, sigma^2)
    y, _ = lfilter([1.0], [1.0, -phi], w, zi=[phi * x0])
    y[0] = x0
    return np.asarray(y, dtype=np.float64)


def wheel_speeds(
    log: VehicleLog, cfg: SensorConfig, rng: np.random.Generator, start_ns: int
) -> WheelSpeedStream:
    """ABS wheel speeds by edge timing on a toothed ring.

    Tooth edge n of wheel i passes the pick-up when the wheel angle reaches
    phi_i + n * pitch + e_i[n mod N] (e: tooth pitch errors, zero mean around the ring). Edge
    times are captured by a timer of resolution ``res`` (floor). At each sample time t the ECU
    takes the edges in (t - T, t] and reports (count - 1) * pitch / (t_last - t_first) -- the
    nominal pitch, so pitch errors show up as speed noise. Without two edges in the period it
    holds the last speed, decaying as pitch / (t - t_last_edge), and reports 0 once the last
    edge is older than the timeout.
    """
    teeth = cfg.wheel_speed_teeth
    pitch = 2.0 * math.pi / teeth
    period_s = 1.0 / cfg.wheel_speed_rate_hz
    res = cfg.wheel_speed_timer_resolution_s
    offset = cfg.wheel_speed_time_offset_s
    t_end = float(log.t_s[-1])
    # a sample stamped t measures the window ending at t - offset (true time)
    rel_ns, t_stamp = _stamps(
        cfg.wheel_speed_rate_hz, max(period_s, period_s + offset), t_end + offset
    )
    t_meas = t_stamp - offset
    dt = log.dt_s
    out = np.zeros((t_stamp.size, 4))
    omegas = log.wheel_omega_rad_s
    if cfg.wheel_speed_rear_locked:
        omegas = omegas.copy()
        omegas[:, 2] = omegas[:, 3] = 0.5 * (omegas[:, 2] + omegas[:, 3])
    for i in range(4):
        omega = omegas[:, i]
        # wheel angle by the trapezoidal rule; a tiny ramp keeps it strictly increasing at rest
        theta = np.concatenate([[0.0], np.cumsum(0.5 * (omega[1:] + omega[:-1]) * dt)])
        theta += np.arange(theta.size) * 1e-12
        errors = rng.standard_normal(teeth) * cfg.wheel_speed_tooth_pitch_error_std_rad
        errors = np.clip(errors - errors.mean(), -0.4 * pitch, 0.4 * pitch)
        phase = float(rng.uniform(0.0, pitch))
        n_max = int((theta[-1] - phase) / pitch) + 2
        idx = np.arange(n_max)
        angles = phase + idx * pitch + errors[idx % teeth]
        angles = angles[(angles > 0.0) & (angles < theta[-1])]
        edges = np.interp(angles, theta, log.t_s)
        if res > 0.0:
            edges = np.floor(edges / res) * res
        hi = np.searchsorted(edges, t_meas, side="right")  # edges <= t
        lo = np.searchsorted(edges, t_meas - period_s, side="right")  # edges > t - T
        count = hi - lo
        speed = np.zeros(t_stamp.size)
        ok = count >= 2
        span = np.where(
            ok, edges[np.maximum(hi - 1, 0)] - edges[np.minimum(lo, edges.size - 1)], 1.0
        )
        ok &= span > 0.0
        speed[ok] = (count[ok] - 1) * pitch / span[ok]
        # hold (decaying) when fewer than two edges fell in the period
        for k in np.flatnonzero(~ok):
            j = hi[k] - 1
            if j < 1 or t_meas[k] - edges[j] > cfg.wheel_speed_timeout_s:
                continue
            gap = edges[j] - edges[j - 1]
            since = t_meas[k] - edges[j]
            held = pitch / gap if gap > 0.0 else 0.0
            speed[k] = min(held, pitch / since) if since > 0.0 else held
        out[:, i] = speed
    if cfg.wheel_speed_lost_wheel != "none":
        lost_from = cfg.wheel_speed_lost_from_s
        dead = (t_stamp >= lost_from) & (t_stamp < lost_from + cfg.wheel_speed_lost_duration_s)
        out[dead, WHEEL_INDEX[cfg.wheel_speed_lost_wheel]] = 0.0
    return WheelSpeedStream(t_ns=start_ns + rel_ns, wheel_speed_rad_s=out)


def steering(
    log: VehicleLog, cfg: SensorConfig, rng: np.random.Generator, start_ns: int
) -> SteeringStream:
    """Mean road-wheel angle + offset + white noise, quantized to the CAN resolution."""
    rel_ns, t = _stamps(cfg.steering_rate_hz, 0.0, float(log.t_s[-1]))
    angle = _interp(log, log.steer_rad, t) + cfg.steering_offset_rad
    angle = angle + rng.standard_normal(t.size) * cfg.steering_noise_std_rad
    if cfg.steering_resolution_rad > 0.0:
        angle = np.round(angle / cfg.steering_resolution_rad) * cfg.steering_resolution_rad
    return SteeringStream(t_ns=start_ns + rel_ns, angle_rad=angle)


def imu(
    log: VehicleLog,
    cfg: SensorConfig,
    vehicle: VehicleParams,
    rng: np.random.Generator,
    start_ns: int,
) -> ImuStream:
    """Gyro and accelerometer in base_link axes at ``vehicle.imu_position_m``.

    Specific force f = a_imu - g_body: planar motion on a road of grade theta (nose up positive)
    gives f = (a_x + g sin theta, a_y, g cos theta); at rest z reads +9.81.
    """
    period_s = 1.0 / cfg.imu_rate_hz
    rel_ns, t = _stamps(cfg.imu_rate_hz, 0.0, float(log.t_s[-1]))
    m = t.size
    r = _interp(log, log.yaw_rate_rad_s, t)
    dr = _interp(log, log.yaw_accel_rad_s2, t)
    acc = _interp(log, log.acceleration_m_s2, t)
    grade = _interp(log, log.grade_rad, t)
    px, py, _ = vehicle.imu_position_m
    # rigid body: a_p = a_o + dr z x p - r^2 p   (p = IMU position in base_link)
    ax = acc[:, 0] - dr * py - r * r * px
    ay = acc[:, 1] + dr * px - r * r * py
    g = GRAVITY_M_S2
    f_true = np.column_stack([ax + g * np.sin(grade), ay, g * np.cos(grade)])
    w_true = np.column_stack([np.zeros(m), np.zeros(m), r])
    gyro_bias = (
        _bias_walk(
            rng,
            m,
            cfg.gyro_bias_initial_std_rad_s,
            cfg.gyro_bias_random_walk_rad_s_sqrt_s,
            period_s,
        )
        + np.asarray(cfg.gyro_bias_rad_s)[None, :]
    )
    acc_bias = _bias_walk(
        rng, m, cfg.accel_bias_initial_std_m_s2, cfg.accel_bias_random_walk_m_s2_sqrt_s, period_s
    )
    gyro = w_true + gyro_bias + rng.standard_normal((m, 3)) * cfg.gyro_noise_std_rad_s
    accel = f_true + acc_bias + rng.standard_normal((m, 3)) * cfg.accel_noise_std_m_s2
    if cfg.imu_upside_down:
        # injected: turned by 180 degrees about x, y and z change sign
        gyro, accel = gyro * [1.0, -1.0, -1.0], accel * [1.0, -1.0, -1.0]
    if cfg.imu_mounting_yaw_deg:
        # injected: the IMU turned by psi about z reports R(-psi) times the base_link vectors
        c, s = (
            math.cos(math.radians(cfg.imu_mounting_yaw_deg)),
            math.sin(math.radians(cfg.imu_mounting_yaw_deg)),
        )
        to_imu = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
        gyro, accel = gyro @ to_imu.T, accel @ to_imu.T
    if cfg.imu_mounting_pitch_deg:
        # injected: pitched nose-up by th, the IMU's x axis is (cos th, 0, sin th) and its z
        # axis (-sin th, 0, cos th) in base_link: at rest it reads f_x = g sin th
        c, s = (
            math.cos(math.radians(cfg.imu_mounting_pitch_deg)),
            math.sin(math.radians(cfg.imu_mounting_pitch_deg)),
        )
        to_imu = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
        gyro, accel = gyro @ to_imu.T, accel @ to_imu.T
    return ImuStream(
        t_ns=start_ns + rel_ns,
        angular_velocity_rad_s=gyro,
        linear_acceleration_m_s2=accel,
        gyro_noise_std_rad_s=cfg.gyro_noise_std_rad_s,
        accel_noise_std_m_s2=cfg.accel_noise_std_m_s2,
    )


def antenna_enu(log: VehicleLog, vehicle: VehicleParams, t_s: F64) -> tuple[F64, F64]:
    """True ENU position (m, 3) and velocity (m, 3) of the GNSS antenna at times ``t_s``."""
    pos = _interp(log, log.position_enu_m, t_s)
    yaw = _interp(log, np.unwrap(log.yaw_rad), t_s)
    vel = _interp(log, log.velocity_m_s, t_s)
    r = _interp(log, log.yaw_rate_rad_s, t_s)
    grade = _interp(log, log.grade_rad, t_s)
    lx, ly, lz = vehicle.gnss_antenna_position_m
    c, s = np.cos(yaw), np.sin(yaw)
    # p_ant = p + R(psi) [lx, ly] (+ lz up); v_ant(body) = v + r z x l
    e = pos[:, 0] + c * lx - s * ly
    n = pos[:, 1] + s * lx + c * ly
    u = pos[:, 2] + lz
    vbx = vel[:, 0] * np.cos(grade) - r * ly
    vby = vel[:, 1] + r * lx
    v_enu = np.column_stack([c * vbx - s * vby, s * vbx + c * vby, vel[:, 0] * np.sin(grade)])
    return np.column_stack([e, n, u]), v_enu


def gnss(
    log: VehicleLog,
    cfg: SensorConfig,
    vehicle: VehicleParams,
    ltp: LocalTangentPlane,
    rng: np.random.Generator,
    start_ns: int,
) -> GnssStream:
    """Antenna fixes: truth + white noise + first-order Gauss-Markov error, in WGS-84, and
    optionally the Doppler velocity (truth + white noise) with the same stamps.

    A fix stamped t describes the antenna at t - ``gnss_latency_s``, its velocity at
    t - ``gnss_velocity_latency_s`` (injected latencies); the stamps run
    ``gnss_clock_offset_s`` ahead of the other sensors' clock.
    """
    period_s = 1.0 / cfg.gnss_rate_hz
    latency = cfg.gnss_latency_s
    rel_ns, t = _stamps(cfg.gnss_rate_hz, latency, float(log.t_s[-1]) + latency)
    m = t.size
    pos, vel = antenna_enu(log, vehicle, t - latency)
    white_std = np.array(
        [cfg.gnss_white_std_m, cfg.gnss_white_std_m, cfg.gnss_white_vertical_std_m]
    )
    gm_std = (cfg.gnss_gm_std_m, cfg.gnss_gm_std_m, cfg.gnss_gm_vertical_std_m)
    gm = np.column_stack([_gauss_markov(rng, m, s, cfg.gnss_gm_tau_s, period_s) for s in gm_std])
    meas = pos + gm + rng.standard_normal((m, 3)) * white_std[None, :]
    lat, lon, alt = ltp.to_lla(meas[:, 0], meas[:, 1], meas[:, 2])
    var = (cfg.gnss_covariance_scale**2) * np.array(
        [cfg.gnss_total_std_m**2, cfg.gnss_total_std_m**2, cfg.gnss_total_vertical_std_m**2]
    )
    cov = np.broadcast_to(np.diag(var), (m, 3, 3)).copy()
    vel_noise = rng.standard_normal((m, 3))
    vel_meas = vel_cov = None
    if cfg.gnss_velocity_enabled:
        # the velocity describes the antenna at t - gnss_velocity_latency_s (t the stamp)
        _, vel = antenna_enu(log, vehicle, t - cfg.gnss_velocity_latency_s)
        v_std = np.array(
            [
                cfg.gnss_velocity_noise_std_m_s,
                cfg.gnss_velocity_noise_std_m_s,
                cfg.gnss_velocity_vertical_noise_std_m_s,
            ]
        )
        vel_meas = vel + vel_noise * v_std[None, :]
        stated = cfg.gnss_velocity_covariance_scale * v_std
        vel_cov = np.broadcast_to(np.diag(stated**2), (m, 3, 3)).copy()
    out_from = cfg.gnss_outage_from_s
    keep = ~((t >= out_from) & (t < out_from + cfg.gnss_outage_duration_s))
    return GnssStream(
        t_ns=start_ns + rel_ns[keep] + round(cfg.gnss_clock_offset_s * 1e9),
        lat_deg=lat[keep],
        lon_deg=lon[keep],
        alt_m=alt[keep],
        position_covariance_m2=cov[keep],
        velocity_enu_m_s=None if vel_meas is None else vel_meas[keep],
        velocity_covariance_m2_s2=None if vel_cov is None else vel_cov[keep],
    )


def tire_forces(
    log: VehicleLog, cfg: SensorConfig, rng: np.random.Generator, start_ns: int
) -> TireForceStream:
    """Tyre forces in the wheel frames on the equipped wheels (+ white noise); 0 elsewhere."""
    rel_ns, t = _stamps(cfg.tire_force_rate_hz, 0.0, float(log.t_s[-1]))
    m = t.size
    valid = np.zeros((m, 4), dtype=bool)
    for w in cfg.tire_force_wheels:
        valid[:, WHEEL_INDEX[w]] = True
    noise = rng.standard_normal((3, m, 4))
    arrays = []
    for j, (values, std) in enumerate(
        (
            (log.fx_n, cfg.tire_force_noise_fx_n),
            (log.fy_n, cfg.tire_force_noise_fy_n),
            (log.fz_n, cfg.tire_force_noise_fz_n),
        )
    ):
        a = _interp(log, values, t) + noise[j] * std
        arrays.append(np.where(valid, a, 0.0))
    return TireForceStream(
        t_ns=start_ns + rel_ns, fx_n=arrays[0], fy_n=arrays[1], fz_n=arrays[2], valid=valid
    )


def truth(log: VehicleLog, ltp: LocalTangentPlane, rate_hz: float, start_ns: int) -> TruthStream:
    """The true state of base_link at ``rate_hz`` (a divisor of the integration rate)."""
    step = max(1, round(1.0 / (rate_hz * log.dt_s)))
    idx = np.arange(0, log.t_s.size, step)
    rel_ns = np.round(log.t_s[idx] * 1e9).astype(np.int64)
    pos = log.position_enu_m[idx]
    lat, lon, alt = ltp.to_lla(pos[:, 0], pos[:, 1], pos[:, 2])
    yaw = (log.yaw_rad[idx] + math.pi) % (2.0 * math.pi) - math.pi
    return TruthStream(
        t_ns=start_ns + rel_ns,
        lat_deg=lat,
        lon_deg=lon,
        alt_m=alt,
        position_enu_m=pos.copy(),
        yaw_rad=yaw,
        velocity_m_s=log.velocity_m_s[idx].copy(),
        yaw_rate_rad_s=log.yaw_rate_rad_s[idx].copy(),
        acceleration_m_s2=log.acceleration_m_s2[idx].copy(),
        wheel_radius_m=log.wheel_radius_m[idx].copy(),
        tire_pressure_pa=log.tire_pressure_pa[idx].copy(),
        stiffness=log.stiffness[idx].copy(),
        cx_rear_n=log.cx_rear_n[idx].copy(),
    )
