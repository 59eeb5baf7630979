"""Axle cornering stiffness from a drive with a lateral-velocity reference (a prior check).

With the lateral velocity measured (an RTK INS, an optical sensor), the slip angles of eq. (4)
and the two axle forces of the single-track model (Berntorp and Di Cairano 2018, eq. 1-6, with
no longitudinal force) follow from the signals alone::

    m ay        = Fyf cos(delta) + Fyr
    Iz d(r)/dt  = lf Fyf cos(delta) - lr Fyr

A least-squares fit of the stiffness MPF's own tyre curve (``stiffness_model
.lateral_slip_function`` with the friction-limited peak ``mu Fz``) to each axle then gives the
cornering stiffness pair that the MPF's model needs on that car: a check of its nominal
stiffness (the prior) against the data, and of how much of the yaw acceleration the model's
yaw balance explains. This reads a reference the estimator does not get; it is an evaluation
tool, not an estimator.

Shapes: every signal is (M,) on one time grid; forces in N, slips in rad.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import savgol_filter

from tire_estimation.core.arrays import F64
from tire_estimation.core.stiffness.model import (
    SingleTrackParams,
    lateral_slip_function,
    slip_angles,
)
from tire_estimation.core.vehicle import VehicleParams


@dataclass(frozen=True)
class AxleFit:
    """Result of :func:`fit_axles`.

    Attributes:
        cornering_stiffness_front_n_rad / _rear_n_rad: fitted axle cornering stiffness, N/rad.
        force_rmse_front_n / _rear_n: RMS of the axle-force residual of the fit, N.
        yaw_moment_r2: share of the variance of ``Iz d(r)/dt`` that the fitted forces' yaw moment
            explains (1 - var(residual) / var(Iz d(r)/dt)), 1.
        n_samples: samples used, 1.
    """

    cornering_stiffness_front_n_rad: float
    cornering_stiffness_rear_n_rad: float
    force_rmse_front_n: float
    force_rmse_rear_n: float
    yaw_moment_r2: float
    n_samples: int


def _smooth(x: F64, window: int) -> F64:
    return x if window <= 1 else savgol_filter(x, window, 2)


def reference_slip_angles(
    vx_m_s: F64, vy_m_s: F64, yaw_rate_rad_s: F64, delta_rad: F64, vehicle: VehicleParams
) -> tuple[F64, F64]:
    """Front and rear slip angles from the measured velocities (eq. 4), rad, (M,) each."""
    x = np.column_stack([vx_m_s, vy_m_s, yaw_rate_rad_s]).astype(float)
    # eq. (4) with delta = 0, then alpha_f += delta (the MPF's own slip_angles, per sample)
    alpha_f, alpha_r = slip_angles(x, 0.0, SingleTrackParams.from_vehicle(vehicle))
    return alpha_f + np.asarray(delta_rad, dtype=float), alpha_r


def axle_forces_from_motion(
    accel_y_m_s2: F64, yaw_accel_rad_s2: F64, delta_rad: F64, vehicle: VehicleParams
) -> tuple[F64, F64]:
    """Front and rear axle lateral forces that produce the measured ay and d(r)/dt, N.

    Solves ``m ay = Fyf cos(delta) + Fyr`` and ``Iz dr/dt = lf Fyf cos(delta) - lr Fyr``
    (eq. 1 and 6 of the single-track model without longitudinal forces).
    """
    m, iz = vehicle.mass_kg, vehicle.yaw_inertia_kg_m2
    lf, lr = vehicle.cg_to_front_axle_m, vehicle.cg_to_rear_axle_m
    wheelbase = lf + lr
    # Fyf cos(delta) = (m ay lr + Iz dr/dt) / L
    front = (m * accel_y_m_s2 * lr + iz * yaw_accel_rad_s2) / (wheelbase * np.cos(delta_rad))
    # Fyr = (m ay lf - Iz dr/dt) / L
    rear = (m * accel_y_m_s2 * lf - iz * yaw_accel_rad_s2) / wheelbase
    return front, rear


def axle_curve(alpha_rad: F64, stiffness_n_rad: float, peak_force_n: float) -> F64:
    """The MPF's tyre: ``C phi(alpha)`` with ``alpha_s = peak / C`` (linear if peak = 0), N."""
    sat = peak_force_n / stiffness_n_rad if peak_force_n > 0.0 else 0.0
    return stiffness_n_rad * lateral_slip_function(alpha_rad, sat)


def fit_axle_stiffness(alpha_rad: F64, force_n: F64, peak_force_n: float) -> float:
    """Least-squares cornering stiffness of one axle, N/rad.

    ``peak_force_n`` = ``mu Fz`` of the friction-limited tanh tyre; 0 fits the linear tyre
    ``Fy = C alpha`` (closed form).

    Raises:
        ValueError: no slip in the data (all ``alpha_rad`` zero) or sizes differ.
    """
    a = np.asarray(alpha_rad, dtype=float)
    f = np.asarray(force_n, dtype=float)
    if a.shape != f.shape:
        raise ValueError(f"alpha_rad {a.shape} and force_n {f.shape} differ in shape")
    saa = float(np.sum(a * a))
    if saa <= 0.0:
        raise ValueError("alpha_rad is all zero: no slip to fit a stiffness to")
    linear = float(np.sum(a * f)) / saa
    if peak_force_n <= 0.0:
        return linear
    scale = max(abs(linear), 1.0)
    res = least_squares(
        lambda p: axle_curve(a, p[0] * scale, peak_force_n) - f,
        x0=[1.0],
        bounds=([1e-3], [1e3]),
    )
    return float(res.x[0] * scale)


def fit_axles(
    vehicle: VehicleParams,
    vx_m_s: F64,
    vy_m_s: F64,
    yaw_rate_rad_s: F64,
    accel_y_m_s2: F64,
    yaw_accel_rad_s2: F64,
    delta_rad: F64,
    friction_coefficient: float = 0.0,
    smooth_samples: int = 1,
) -> AxleFit:
    """Fit both axles' cornering stiffness to a drive with a vY reference.

    ``friction_coefficient`` > 0 fits the friction-limited tanh tyre with peak ``mu Fz`` at the
    static axle loads; 0 the linear tyre. ``smooth_samples`` (odd, >= 3 to act) smooths the
    slips and forces with a quadratic Savitzky-Golay window first, against the noise of the
    yaw acceleration.

    Raises:
        ValueError: signals of different lengths, fewer than 10 samples, an even smoothing
            window or a negative friction coefficient.
    """
    sig = [
        np.asarray(x, dtype=float)
        for x in (vx_m_s, vy_m_s, yaw_rate_rad_s, accel_y_m_s2, yaw_accel_rad_s2, delta_rad)
    ]
    n = sig[0].size
    if any(x.shape != (n,) for x in sig):
        raise ValueError(f"signals must all be (M,); got {[x.shape for x in sig]}")
    if n < 10:
        raise ValueError(f"{n} samples: need at least 10")
    if smooth_samples > 1 and smooth_samples % 2 == 0:
        raise ValueError(f"smooth_samples={smooth_samples}: must be odd")
    if friction_coefficient < 0.0:
        raise ValueError(f"friction_coefficient={friction_coefficient}: must be >= 0")
    vx, vy, r, ay, rdot, delta = sig
    alpha_f, alpha_r = reference_slip_angles(vx, vy, r, delta, vehicle)
    fyf, fyr = axle_forces_from_motion(ay, rdot, delta, vehicle)
    alpha_f, alpha_r, fyf, fyr = (_smooth(x, smooth_samples) for x in (alpha_f, alpha_r, fyf, fyr))
    lf, lr = vehicle.cg_to_front_axle_m, vehicle.cg_to_rear_axle_m
    # the MPF's peaks mu Fz at the static axle loads: alpha_s,n C_n (SingleTrackParams)
    mpf = SingleTrackParams.from_vehicle(vehicle, friction_coefficient=friction_coefficient)
    peak_f = mpf.saturation_slip_front_rad * float(mpf.nominal[1])
    peak_r = mpf.saturation_slip_rear_rad * float(mpf.nominal[2])
    c_f = fit_axle_stiffness(alpha_f, fyf, peak_f)
    c_r = fit_axle_stiffness(alpha_r, fyr, peak_r)
    model_f = axle_curve(alpha_f, c_f, peak_f)
    model_r = axle_curve(alpha_r, c_r, peak_r)
    iz_rdot = vehicle.yaw_inertia_kg_m2 * _smooth(rdot, smooth_samples)
    # eq. (6) Iz dr/dt = lf Fyf cos(delta) - lr Fyr, with the fitted forces
    moment = lf * model_f * np.cos(delta) - lr * model_r
    var = float(np.var(iz_rdot))
    r2 = 1.0 - float(np.var(moment - iz_rdot)) / var if var > 0.0 else float("nan")
    return AxleFit(
        cornering_stiffness_front_n_rad=c_f,
        cornering_stiffness_rear_n_rad=c_r,
        force_rmse_front_n=float(np.sqrt(np.mean((model_f - fyf) ** 2))),
        force_rmse_rear_n=float(np.sqrt(np.mean((model_r - fyr) ** 2))),
        yaw_moment_r2=r2,
        n_samples=n,
    )


def kinematic_accel_ratio(
    accel_y_m_s2: F64,
    vx_m_s: F64,
    vy_m_s: F64,
    yaw_rate_rad_s: F64,
    dt_s: float,
    smooth_samples: int = 51,
) -> float:
    """Slope of the measured ay over the kinematic ``dvY/dt + vX r``, 1.

    1 for an accelerometer in the horizontal plane; ``1 + c_phi g`` (the paper's roll gain,
    Sec. II-A) when the body roll tilts it into gravity. Both sides are
    smoothed (quadratic Savitzky-Golay, ``smooth_samples``) before the regression.

    Raises:
        ValueError: ``dt_s`` <= 0 or ``smooth_samples`` even or < 5.
    """
    if not dt_s > 0.0:
        raise ValueError(f"dt_s={dt_s}: must be > 0")
    if smooth_samples < 5 or smooth_samples % 2 == 0:
        raise ValueError(f"smooth_samples={smooth_samples}: must be odd and >= 5")
    ay = savgol_filter(np.asarray(accel_y_m_s2, dtype=float), smooth_samples, 2)
    dvy = savgol_filter(np.asarray(vy_m_s, dtype=float), smooth_samples, 2, deriv=1, delta=dt_s)
    vxr = savgol_filter(np.asarray(vx_m_s, dtype=float) * yaw_rate_rad_s, smooth_samples, 2)
    kin = dvy + vxr
    kc = kin - kin.mean()
    return float(np.sum(kc * (ay - ay.mean())) / np.sum(kc * kc))
