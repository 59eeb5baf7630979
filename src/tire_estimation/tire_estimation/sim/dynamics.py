"""Planar vehicle dynamics: integrate a :class:`~tire_estimation.sim.scenarios.Plan`.

State, in ENU (REP-103/105): position (x east, y north, z up) of ``base_link`` (centre of the
rear axle on the ground), yaw psi (0 = east, counter-clockwise), body velocities vx (forward) and
vy_cg (left, at the centre of gravity), yaw rate r, road-wheel steer angle delta (first-order
steering actuator) and travelled distance s.

Model (Pacejka "Tyre and Vehicle Dynamics" ch. 1; Berntorp & Di Cairano 2018 eq. 1 extended to
two tracks and load transfer):

* Each wheel i sits at (xi, yi) from the centre of gravity; its centre moves with
  (vx - r yi, vy_cg + r xi) in the body; front wheels are rotated by delta.
* Lateral force per wheel from the Magic Formula of its slip angle, peak mu Fz_i (reduced by the
  friction circle for the longitudinal force), small-slip slope = configured stiffness.
* Longitudinal forces are quasi-static: the driver's force demand is split over the driven wheels
  (drive) or over all wheels (braking); the slip is the inverse Magic Formula of that force.
  Free-rolling wheels have zero slip (rolling resistance acts on the body).
* Loads: static axle loads plus longitudinal (m ax h / L) and lateral (m ay h / track, split
  like the static loads) transfer, using the accelerations of the previous step.
* Integration at ``plan.dt_s`` (5 ms): semi-implicit Euler for the velocities, then the
  trapezoidal rule on the old and new velocities for the pose (heading and position). Below
  2 m/s the lateral state is blended towards the kinematic model
  (r = vx tan(delta) / L, no lateral velocity at the rear axle), fully kinematic below 0.5 m/s.

The loop uses scalar ``math`` on Python floats: NumPy on 4-element arrays per step would be
slower by an order of magnitude.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.sim.config import SensorConfig
from tire_estimation.sim.scenarios import Plan
from tire_estimation.sim.tires import MIN_FZ_N, TireModelConfig

#: Standard gravity used by the simulator, m/s^2.
GRAVITY_M_S2 = 9.81
#: Above this speed the dynamic (slip-angle) model is used alone, m/s.
KINEMATIC_BLEND_HIGH_M_S = 2.0
#: Below this speed the kinematic model is used alone, m/s.
KINEMATIC_BLEND_LOW_M_S = 0.5
#: Yaw-rate feedback of the path-following driver, rad of steer per rad/s of yaw-rate error.
STEER_YAW_FEEDBACK_S = 0.1


@dataclass(frozen=True)
class VehicleLog:
    """The internal state on the integration grid (every ``dt_s``); per-wheel arrays (n, 4).

    Positions/velocities/accelerations are those of ``base_link``; ``yaw_rad`` is unwrapped.
    Forces are in each wheel's frame (x along the wheel heading, y left, z up).
    """

    dt_s: float
    t_s: F64
    position_enu_m: F64  # (n, 3)
    yaw_rad: F64
    velocity_m_s: F64  # (n, 2) [vx, vy] of base_link in base_link axes
    yaw_rate_rad_s: F64
    yaw_accel_rad_s2: F64
    acceleration_m_s2: F64  # (n, 2) kinematic, base_link
    grade_rad: F64
    steer_rad: F64
    wheel_omega_rad_s: F64
    wheel_radius_m: F64
    wheel_rolling_speed_m_s: F64
    wheel_slip: F64
    fx_n: F64
    fy_n: F64
    fz_n: F64
    stiffness: F64  # (n, 3) [cx_front N, cy_front N/rad, cy_rear N/rad] axle values
    cx_rear_n: F64  # (n,) rear-axle longitudinal stiffness, N (scaled with cx_front)
    tire_pressure_pa: F64


def integrate(
    plan: Plan,
    vehicle: VehicleParams,
    tires: TireModelConfig,
    sensors: SensorConfig,
    radius_offset_m: tuple[float, float, float, float],
) -> VehicleLog:
    """Run the vehicle through ``plan`` and log the state at every step."""
    n = plan.n_steps
    dt = plan.dt_s
    g = GRAVITY_M_S2
    m = vehicle.mass_kg
    iz = vehicle.yaw_inertia_kg_m2
    lf = vehicle.cg_to_front_axle_m
    lr = vehicle.cg_to_rear_axle_m
    wb = lf + lr
    h = vehicle.cg_height_m
    track = vehicle.track_width_m
    half = 0.5 * track
    xs = (lf, lf, -lr, -lr)  # wheel x from the centre of gravity
    ys = (half, -half, half, -half)
    is_front = (True, True, False, False)
    driven = {"front": (1, 1, 0, 0), "rear": (0, 0, 1, 1), "all": (1, 1, 1, 1)}[vehicle.drive]
    n_driven = sum(driven)
    # static loads: Fz_front_axle = m g lr / L, Fz_rear_axle = m g lf / L, split evenly
    fz_static = (m * g * lr / wb / 2,) * 2 + (m * g * lf / wb / 2,) * 2
    cy_nom = (vehicle.cornering_stiffness_front_n_rad / 2,) * 2 + (
        vehicle.cornering_stiffness_rear_n_rad / 2,
    ) * 2
    cx_nom = (vehicle.longitudinal_stiffness_front_n / 2,) * 2 + (
        vehicle.longitudinal_stiffness_rear_n / 2,
    ) * 2
    # understeer gradient of the nominal vehicle, rad per m/s^2 (driver feed-forward):
    # K = m / L (lr / Cf - lf / Cr)
    k_us = (
        m
        / wb
        * (
            lr / vehicle.cornering_stiffness_front_n_rad
            - lf / vehicle.cornering_stiffness_rear_n_rad
        )
    )
    c_lat, e_lat, c_lon = (
        tires.lateral_shape_c,
        tires.lateral_curvature_e,
        tires.longitudinal_shape_c,
    )
    crr_n = tires.rolling_resistance_coefficient * m * g
    drag_k = 0.5 * tires.air_density_kg_m3 * tires.drag_area_m2
    p_max = tires.max_drive_power_w
    brake_share = (
        tires.brake_front_share / 2,
        tires.brake_front_share / 2,
        (1 - tires.brake_front_share) / 2,
        (1 - tires.brake_front_share) / 2,
    )
    c_speed = sensors.radius_speed_coefficient_m_per_m2_s2
    c_load = sensors.radius_load_coefficient_m_per_n
    grade_amp = sensors.road_grade_amplitude_rad
    grade_k = 2.0 * math.pi / sensors.road_grade_wavelength_m

    # effective rolling radius without the dynamic terms:
    # r = r_nominal + offset_i + (p - p_nominal) * sensitivity   (0.03 mm/kPa default)
    pressure_kpa = plan.pressure_kpa
    r_base = (
        vehicle.nominal_tire_radius_m
        + np.asarray(radius_offset_m)[None, :]
        + (pressure_kpa - tires.nominal_pressure_kpa)
        * tires.pressure_sensitivity_mm_per_kpa
        * 1e-3
    )
    r_base_cols = [r_base[:, i].tolist() for i in range(4)]
    v_ref = plan.speed_ref_m_s.tolist()
    a_ref = plan.accel_ref_m_s2.tolist()
    kappa_ref = None if plan.curvature_ref_1_m is None else plan.curvature_ref_1_m.tolist()
    steer_cmd = None if plan.steer_cmd_rad is None else plan.steer_cmd_rad.tolist()
    extra = None if plan.extra_drive_force_n is None else plan.extra_drive_force_n.tolist()
    sf = plan.stiffness_factor
    sf_cx, sf_cyf, sf_cyr = (sf[:, j].tolist() for j in range(3))
    mu_l = plan.mu.tolist()
    kv = plan.speed_gain_1_s
    steer_alpha = 1.0 - math.exp(-dt / plan.steer_lag_s)

    # state
    x = y = z = s = 0.0
    psi = plan.initial_yaw_rad
    vx = plan.initial_speed_m_s
    vy = plan.initial_lateral_velocity_m_s + 0.0  # at the CG
    r = plan.initial_yaw_rate_rad_s
    delta = 0.0
    ax_cg = ay_cg = 0.0

    fz = [0.0] * 4
    fxw = [0.0] * 4
    rows: list[tuple[float, ...]] = []
    wrows: list[tuple[float, ...]] = []

    for k in range(n):
        mu = mu_l[k]
        grade = grade_amp * math.sin(grade_k * s) if grade_amp else 0.0
        # --- driver: speed controller, F = m (a_ref + kv (v_ref - v)) + resistances ---
        f_aero = drag_k * vx * abs(vx)
        f_rr = crr_n * min(1.0, max(vx, 0.0) / 0.1)
        f_grade = m * g * math.sin(grade)
        f_cmd = m * (a_ref[k] + kv * (v_ref[k] - vx)) + f_aero + f_rr + f_grade
        # --- driver: steering ---
        if steer_cmd is not None:
            d_cmd = steer_cmd[k]
        else:
            kap = kappa_ref[k]  # type: ignore[index]
            # delta = atan(L kappa) + K_us v^2 kappa + feedback on the yaw-rate error
            d_cmd = (
                math.atan(wb * kap) + k_us * vx * vx * kap + STEER_YAW_FEEDBACK_S * (vx * kap - r)
            )
        d_cmd = max(-0.6, min(0.6, d_cmd))
        delta += steer_alpha * (d_cmd - delta)
        # --- vertical loads with load transfer from the previous accelerations ---
        d_long = m * ax_cg * h / wb / 2.0
        d_lat_f = m * ay_cg * h / track * (lr / wb)
        d_lat_r = m * ay_cg * h / track * (lf / wb)
        fz[0] = max(MIN_FZ_N, fz_static[0] - d_long - d_lat_f)
        fz[1] = max(MIN_FZ_N, fz_static[1] - d_long + d_lat_f)
        fz[2] = max(MIN_FZ_N, fz_static[2] + d_long - d_lat_r)
        fz[3] = max(MIN_FZ_N, fz_static[3] + d_long + d_lat_r)
        # --- longitudinal force per wheel (quasi-static) ---
        if extra is not None:
            f_drive = f_cmd + extra[k]
            for i in range(4):
                fxw[i] = f_drive / n_driven if driven[i] else 0.0
        elif f_cmd >= 0.0:
            f_drive = min(f_cmd, p_max / max(vx, 5.0))
            for i in range(4):
                fxw[i] = f_drive / n_driven if driven[i] else 0.0
        else:
            for i in range(4):
                fxw[i] = f_cmd * brake_share[i]
        cd = math.cos(delta)
        sd = math.sin(delta)
        sum_fx = sum_fy = mz = 0.0
        cyf = sf_cyf[k]
        cyr = sf_cyr[k]
        cxf = sf_cx[k]
        row_w: list[float] = []
        for i in range(4):
            vxi = vx - r * ys[i]
            vyi = vy + r * xs[i]
            if is_front[i]:
                vxw = vxi * cd + vyi * sd
                vyw = -vxi * sd + vyi * cd
            else:
                vxw, vyw = vxi, vyi
            d_peak = mu * fz[i]
            fx = max(-0.95 * d_peak, min(0.95 * d_peak, fxw[i]))
            # friction circle: lateral peak sqrt(D^2 - Fx^2), slope kept at the stiffness
            dy = math.sqrt(max(d_peak * d_peak - fx * fx, 0.01 * d_peak * d_peak))
            # slip angle alpha = -atan(vy_w / vx_w)  (speed floored at 1 m/s)
            alpha = -math.atan2(vyw, max(abs(vxw), 1.0))
            c_y = cy_nom[i] * (cyf if is_front[i] else cyr)
            bx = c_y / (c_lat * dy) * alpha
            # Magic Formula: Fy = D sin(C atan(B a - E (B a - atan(B a))))
            fy = dy * math.sin(c_lat * math.atan(bx - e_lat * (bx - math.atan(bx))))
            if is_front[i]:
                fxb = fx * cd - fy * sd
                fyb = fx * sd + fy * cd
            else:
                fxb, fyb = fx, fy
            sum_fx += fxb
            sum_fy += fyb
            mz += xs[i] * fyb - ys[i] * fxb
            # longitudinal slip: inverse of Fx = D sin(C atan(B kappa)) (E = 0); 0 if free
            if fx != 0.0:
                ratio = max(-0.999, min(0.999, fx / d_peak))
                slip = math.tan(math.asin(ratio) / c_lon) * (c_lon * d_peak) / (cx_nom[i] * cxf)
            else:
                slip = 0.0
            roll = vxw if vxw > 0.0 else 0.0
            # r_eff = r_base(pressure) + c_v v^2 + c_F (Fz - Fz_static)   (injected effects)
            radius = r_base_cols[i][k] + c_speed * roll * roll + c_load * (fz[i] - fz_static[i])
            # wheel angular speed: omega = v_roll (1 + kappa) / r_eff
            omega = roll * (1.0 + slip) / radius
            row_w += (omega, radius, roll, slip, fx, fy, fz[i])
        # --- rigid-body equations at the centre of gravity ---
        # m (dvx - r vy) = sum Fx - F_aero - F_rr - m g sin(grade)
        # m (dvy + r vx) = sum Fy ;  Iz dr = Mz
        ax_cg = (sum_fx - f_aero - f_rr - f_grade) / m
        ay_cg = sum_fy / m
        dr = mz / iz
        # base_link is at p = (-lr, 0) from the CG: a_p = a_cg + dr z x p - r^2 p
        rows.append(
            (
                x,
                y,
                z,
                psi,
                vx,
                vy - r * lr,
                r,
                dr,
                ax_cg + r * r * lr,
                ay_cg - dr * lr,
                grade,
                delta,
            )
        )
        wrows.append(tuple(row_w))
        # --- velocities: semi-implicit Euler ---
        vx_old, vy_o_old, r_old = vx, vy - r * lr, r
        vx += dt * (ax_cg + r * vy)
        vy += dt * (ay_cg - r * vx)
        r += dt * dr
        if vx < 0.0:
            vx = 0.0
        if vx < KINEMATIC_BLEND_HIGH_M_S:
            w = (vx - KINEMATIC_BLEND_LOW_M_S) / (
                KINEMATIC_BLEND_HIGH_M_S - KINEMATIC_BLEND_LOW_M_S
            )
            w = 0.0 if w < 0.0 else w
            # kinematic single track: r = vx tan(delta) / L, rear-axle lateral velocity 0
            r_kin = vx * math.tan(delta) / wb
            r = w * r + (1.0 - w) * r_kin
            vy = w * vy + (1.0 - w) * r_kin * lr
        # --- pose: trapezoidal rule on the old and new velocities ---
        vy_o = vy - r * lr
        psi_new = psi + 0.5 * dt * (r_old + r)
        cg = math.cos(grade)
        e_old = vx_old * cg * math.cos(psi) - vy_o_old * math.sin(psi)
        n_old = vx_old * cg * math.sin(psi) + vy_o_old * math.cos(psi)
        e_new = vx * cg * math.cos(psi_new) - vy_o * math.sin(psi_new)
        n_new = vx * cg * math.sin(psi_new) + vy_o * math.cos(psi_new)
        x += 0.5 * dt * (e_old + e_new)
        y += 0.5 * dt * (n_old + n_new)
        z += 0.5 * dt * (vx_old + vx) * math.sin(grade)
        s += 0.5 * dt * (vx_old + vx)
        psi = psi_new

    out = np.asarray(rows, dtype=np.float64)
    wa = np.asarray(wrows, dtype=np.float64).reshape(n, 4, 7)
    w_omega, w_radius, w_roll, w_slip, w_fx, w_fy, w_fz = (wa[:, :, j] for j in range(7))
    stiffness = np.column_stack(
        [
            vehicle.longitudinal_stiffness_front_n * sf[:, 0],
            vehicle.cornering_stiffness_front_n_rad * sf[:, 1],
            vehicle.cornering_stiffness_rear_n_rad * sf[:, 2],
        ]
    )
    return VehicleLog(
        dt_s=dt,
        t_s=np.arange(n, dtype=np.float64) * dt,
        position_enu_m=out[:, 0:3].copy(),
        yaw_rad=out[:, 3].copy(),
        velocity_m_s=out[:, 4:6].copy(),
        yaw_rate_rad_s=out[:, 6].copy(),
        yaw_accel_rad_s2=out[:, 7].copy(),
        acceleration_m_s2=out[:, 8:10].copy(),
        grade_rad=out[:, 10].copy(),
        steer_rad=out[:, 11].copy(),
        wheel_omega_rad_s=np.ascontiguousarray(w_omega),
        wheel_radius_m=np.ascontiguousarray(w_radius),
        wheel_rolling_speed_m_s=np.ascontiguousarray(w_roll),
        wheel_slip=np.ascontiguousarray(w_slip),
        fx_n=np.ascontiguousarray(w_fx),
        fy_n=np.ascontiguousarray(w_fy),
        fz_n=np.ascontiguousarray(w_fz),
        stiffness=stiffness,
        cx_rear_n=vehicle.longitudinal_stiffness_rear_n * sf[:, 0],
        tire_pressure_pa=pressure_kpa * 1e3,
    )
