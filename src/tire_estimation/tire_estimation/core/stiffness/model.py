"""Single-track model of Berntorp & Di Cairano, "Tire-stiffness and vehicle-state estimation
based on noise-adaptive particle filtering", IEEE TCST 2018, Section II (eq. 1-12).

Everything is vectorized over particles: states ``x`` are ``(N, 3)`` = ``[vx, vy, r]`` with
``vy`` the lateral velocity at the centre of gravity (CG) and ``r`` the yaw rate; the stiffness
vector is ``C = [Cx, Cy_front, Cy_rear]`` (axle values, N per unit slip and N/rad).

Sign conventions (documented deviations):

* Wheel slip is ``(R w - vx) / max(vx, R w)`` (positive when driving), i.e. the negative of
  eq. (3) as printed, so that ``Fx = Cx * slip`` is a traction force (eq. 2).
* ``Cx`` is the longitudinal stiffness of the driven axle (front by default, as in the paper);
  rear-wheel drive substitutes the rear axle (Sec. II-A); all-wheel drive shares one ``Cx`` on
  both axles (the simulator scales both axles together).
* The IMU sits at ``p`` from the CG; the measured specific force is the rigid-body acceleration
  at ``p`` (``a_p = a_cg + dr z x p - r^2 p``), which stays affine in ``C``.
* Optional lateral saturation (not in the paper, off by default): ``Fy = C * phi(alpha)`` with
  ``phi(alpha) = alpha_s tanh(alpha / alpha_s)`` per axle (:func:`lateral_slip_function`), still
  affine in ``C``. ``C`` stays the small-slip cornering stiffness and the axle's force levels off
  at ``C alpha_s``; with ``alpha_s = mu Fz / C_n`` (static axle load ``Fz``, friction coefficient
  ``mu``) that peak is ``mu Fz`` at the nominal stiffness and scales with the learned ``C / C_n``;
  with ``alpha_s = mu Fz / C`` at the particle's current stiffness (:func:`saturation_slip_at`,
  the estimator's default) the peak is the friction limit ``mu Fz`` itself. Instead of the tanh,
  ``phi`` can be Pacejka's Magic Formula with a given shape factor and curvature factor, scaled
  to the same slope 1 and the same peak ``alpha_s`` (``tyre_shape`` = ``magic_formula``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.validation import in_range
from tire_estimation.core.vehicle import VehicleParams

#: Standard gravity, m/s^2.
GRAVITY_M_S2 = 9.81
#: Speed floor in the slip and slip-angle denominators, m/s.
MIN_SPEED_M_S = 1.0
#: Names of the three estimated stiffnesses (order of ``w`` in eq. 8), front- or all-wheel
#: drive; a rear-driven vehicle's ``Cx`` is its rear axle's (:data:`REAR_DRIVE_NAMES`)
NAMES = ("cx_front", "cy_front", "cy_rear")
#: The same for a rear-driven vehicle.
REAR_DRIVE_NAMES = ("cx_rear", "cy_front", "cy_rear")
#: Shapes of the saturating lateral tyre (:func:`lateral_slip_function`).
TYRE_SHAPES = ("tanh", "magic_formula")
#: The Magic Formula's shape factor C (Pacejka, Tyre and Vehicle Dynamics, 2012: about 1.3
#: laterally, 1.65 longitudinally) and curvature factor E (below 1), as configurations take them.
ShapeFactor = Annotated[float, in_range(1.0, 1.9)]
CurvatureFactor = Annotated[float, in_range(-5.0, 0.99)]
#: Projection bounds of every stiffness (Sec. V), fractions of nominal: wide enough for a
#: tyre on ice (5 %) and a stiff race tyre (300 %), so that they only catch a diverging draw.
MIN_STIFFNESS_FRACTION = 0.05
MAX_STIFFNESS_FRACTION = 3.0
#: Std of the axle-mean wheel speed ``R_w omega`` (ABS edge timing), m/s: the simulator's
#: 48-tooth sensor; carried into ``y`` through the slip (eq. 2-3) it is added to R.
WHEEL_SPEED_NOISE_STD_M_S = 0.035


@dataclass(frozen=True)
class SingleTrackParams:
    """Parameters of the single-track model (SI units).

    Attributes:
        mass_kg: vehicle mass m, kg.
        yaw_inertia_kg_m2: yaw inertia I about the CG, kg m^2.
        lf_m: CG to front axle, m.
        lr_m: CG to rear axle, m.
        imu_x_m: IMU position relative to the CG, forward, m.
        imu_y_m: IMU position relative to the CG, left, m.
        wheel_radius_m: effective wheel radius R_w of eq. (3), m.
        drive: driven axle ``front``, ``rear`` or ``all``.
        nominal: nominal stiffness C_n of eq. (7), (3,) = [Cx, Cy_front, Cy_rear].
        rolling_resistance_n: constant longitudinal resistance, N (0 = paper's Assumption 4).
        drag_n_s2_m2: aerodynamic drag coefficient k in F = k vx^2, N s^2/m^2.
        saturation_slip_front_rad: saturation slip angle alpha_s of the front axle of
            :func:`lateral_slip_function`, rad (0 = linear tyre, eq. 2 as printed).
        saturation_slip_rear_rad: the same for the rear axle, rad (0 = linear).
        tyre_shape: shape of the saturating tyre, ``tanh`` or ``magic_formula``.
        magic_formula_shape_c: shape factor C of the ``magic_formula`` shape, 1.
        magic_formula_curvature_e: curvature factor E of the ``magic_formula`` shape, 1.
    """

    mass_kg: float
    yaw_inertia_kg_m2: float
    lf_m: float
    lr_m: float
    imu_x_m: float
    imu_y_m: float
    wheel_radius_m: float
    drive: str
    nominal: tuple[float, float, float]
    rolling_resistance_n: float = 0.0
    drag_n_s2_m2: float = 0.0
    saturation_slip_front_rad: float = 0.0
    saturation_slip_rear_rad: float = 0.0
    tyre_shape: str = "tanh"
    magic_formula_shape_c: float = 1.3
    magic_formula_curvature_e: float = 0.0

    @property
    def names(self) -> tuple[str, str, str]:
        """Names of ``C`` (the driven axle's ``Cx`` named after it; all-wheel drive: the
        front axle's, both axles scaled together)."""
        return REAR_DRIVE_NAMES if self.drive == "rear" else NAMES

    @staticmethod
    def from_vehicle(
        vehicle: VehicleParams,
        drive: str | None = None,
        wheel_radius_m: float | None = None,
        rolling_resistance_n: float = 0.0,
        drag_n_s2_m2: float = 0.0,
        friction_coefficient: float = 0.0,
        cornering_stiffness_front_n_rad: float | None = None,
        cornering_stiffness_rear_n_rad: float | None = None,
        tyre_shape: str = "tanh",
        magic_formula_shape_c: float = 1.3,
        magic_formula_curvature_e: float = 0.0,
    ) -> SingleTrackParams:
        """Build from :class:`VehicleParams` (``base_link`` at the rear axle: CG at x = lr).

        ``friction_coefficient`` mu > 0 switches on the lateral saturation with ``alpha_s =
        mu Fz / C_n`` per axle (static loads ``Fz_f = m g lr / L``, ``Fz_r = m g lf / L``);
        the cornering stiffnesses override the vehicle's nominal values when given;
        ``tyre_shape``, ``magic_formula_shape_c`` and ``magic_formula_curvature_e`` choose the
        saturating shape (:func:`lateral_slip_function`).
        """
        drv = vehicle.drive if drive is None else drive
        cx = (
            vehicle.longitudinal_stiffness_rear_n
            if drv == "rear"
            else vehicle.longitudinal_stiffness_front_n
        )
        cyf = float(
            vehicle.cornering_stiffness_front_n_rad
            if cornering_stiffness_front_n_rad is None
            else cornering_stiffness_front_n_rad
        )
        cyr = float(
            vehicle.cornering_stiffness_rear_n_rad
            if cornering_stiffness_rear_n_rad is None
            else cornering_stiffness_rear_n_rad
        )
        sat_f = sat_r = 0.0
        if friction_coefficient > 0.0:
            wheelbase = vehicle.lf_m + vehicle.lr_m
            # static axle loads Fz_f = m g lr / L, Fz_r = m g lf / L
            fz_f = vehicle.mass_kg * GRAVITY_M_S2 * vehicle.lr_m / wheelbase
            fz_r = vehicle.mass_kg * GRAVITY_M_S2 * vehicle.lf_m / wheelbase
            # alpha_s = mu Fz / C_n: the peak C_n alpha_s of the tanh tyre is mu Fz
            sat_f = friction_coefficient * fz_f / cyf
            sat_r = friction_coefficient * fz_r / cyr
        return SingleTrackParams(
            mass_kg=vehicle.mass_kg,
            yaw_inertia_kg_m2=vehicle.yaw_inertia_kg_m2,
            lf_m=vehicle.lf_m,
            lr_m=vehicle.lr_m,
            imu_x_m=vehicle.imu_position_m[0] - vehicle.lr_m,
            imu_y_m=vehicle.imu_position_m[1],
            wheel_radius_m=(
                vehicle.nominal_tire_radius_m if wheel_radius_m is None else wheel_radius_m
            ),
            drive=drv,
            nominal=(float(cx), cyf, cyr),
            rolling_resistance_n=rolling_resistance_n,
            drag_n_s2_m2=drag_n_s2_m2,
            saturation_slip_front_rad=sat_f,
            saturation_slip_rear_rad=sat_r,
            tyre_shape=tyre_shape,
            magic_formula_shape_c=magic_formula_shape_c,
            magic_formula_curvature_e=magic_formula_curvature_e,
        )


def wheel_slip(vx_m_s: F64, wheel_speed_m_s: F64 | float) -> F64:
    """Longitudinal wheel slip (eq. 3, sign flipped: positive when driving), shape of inputs.

    ``wheel_speed_m_s`` is ``R_w * omega``; the denominator is floored at ``MIN_SPEED_M_S``.
    """
    vx = np.asarray(vx_m_s, dtype=float)
    rw = np.asarray(wheel_speed_m_s, dtype=float)
    # eq. (3): lambda = (R w - vX) / max(vX, R w)
    return (rw - vx) / np.maximum(np.maximum(vx, rw), MIN_SPEED_M_S)


def lateral_slip_function(
    alpha_rad: F64,
    saturation_slip_rad: float | F64,
    shape: str = "tanh",
    shape_c: float = 1.3,
    curvature_e: float = 0.0,
) -> F64:
    """Effective slip ``phi(alpha)`` of the lateral force ``Fy = C phi(alpha)``, rad.

    ``saturation_slip_rad`` = 0 gives the linear tyre of eq. (2) (``phi = alpha``); > 0 a
    saturating tyre with slope 1 at small slip (``C`` is the cornering stiffness) and peak
    ``C alpha_s``. ``shape`` ``tanh``: ``phi = alpha_s tanh(alpha / alpha_s)`` (76 % of the peak
    at ``alpha = alpha_s``, the peak reached only asymptotically); ``magic_formula``: Pacejka's
    ``phi = alpha_s sin(C atan(u - E (u - atan u)))`` with ``u = alpha / (C alpha_s)``, i.e.
    ``D = C_y alpha_s`` and ``B = 1 / (C alpha_s)`` (shape factor ``shape_c`` C in [1, 2),
    curvature factor ``curvature_e`` E < 1; the force peaks at ``C_y alpha_s`` and falls to
    ``sin(C pi / 2)`` of it at large slip). A per-particle ``saturation_slip_rad`` (N,) (all
    > 0) goes with ``alpha_rad`` (N,).
    """
    sat = np.asarray(saturation_slip_rad, dtype=float)
    if sat.ndim == 0 and sat <= 0.0:
        # eq. (2) Fy = C alpha
        return alpha_rad
    # a per-particle alpha_s = 0 keeps the linear tyre of that particle
    safe = np.where(sat > 0.0, sat, 1.0)
    if shape == "magic_formula":
        # Pacejka: Fy = D sin(C atan(B a - E (B a - atan(B a)))) with D = C_y alpha_s and
        # B = C_y / (C D) = 1 / (C alpha_s), so Fy = C_y phi(a) (affine in C_y, slope C_y at 0)
        u = alpha_rad / (shape_c * safe)
        phi = safe * np.sin(shape_c * np.arctan(u - curvature_e * (u - np.arctan(u))))
    else:
        # Fy = C alpha_s tanh(alpha / alpha_s)  (affine in C; -> C alpha for |alpha| << alpha_s)
        phi = safe * np.tanh(alpha_rad / safe)
    return np.where(sat > 0.0, phi, alpha_rad)


def saturation_slip_at(
    p: SingleTrackParams, cy_front_n_rad: F64, cy_rear_n_rad: F64
) -> tuple[F64, F64]:
    """Saturation slips of a friction-limited tyre at the given cornering stiffnesses, rad.

    ``alpha_s = mu Fz / C``: the peak ``C alpha_s`` of :func:`lateral_slip_function` is then the
    friction limit ``mu Fz`` whatever ``C`` is (with ``p``'s ``alpha_s = mu Fz / C_n`` the peak
    scales with ``C / C_n`` instead). ``cy_*`` (N,) (floored at 1 % of nominal) -> two (N,)
    arrays; zeros where ``p`` has the linear tyre.
    """
    out = []
    for sat_n, c_n, c in (
        (p.saturation_slip_front_rad, p.nominal[1], cy_front_n_rad),
        (p.saturation_slip_rear_rad, p.nominal[2], cy_rear_n_rad),
    ):
        # alpha_s = mu Fz / C = alpha_s,n C_n / C
        out.append(sat_n * c_n / np.maximum(np.asarray(c, dtype=float), 0.01 * c_n))
    return out[0], out[1]


def slip_angles(x: F64, delta_rad: float, p: SingleTrackParams) -> tuple[F64, F64]:
    """Front and rear slip angles (eq. 4), rad; ``x`` (N, 3) -> two (N,) arrays."""
    vx = np.maximum(x[:, 0], MIN_SPEED_M_S)
    vy, r = x[:, 1], x[:, 2]
    # eq. (4) alpha_f = delta - (vY + lf r) / vX
    alpha_f = delta_rad - (vy + p.lf_m * r) / vx
    # eq. (4) alpha_r = (lr r - vY) / vX
    alpha_r = (p.lr_m * r - vy) / vx
    return alpha_f, alpha_r


def force_regressor(
    x: F64,
    delta_rad: float,
    wheel_speed_m_s: tuple[float | F64, float | F64],
    p: SingleTrackParams,
    saturation_slip_rad: tuple[F64, F64] | None = None,
) -> F64:
    """Matrix ``A`` (N, 3, 3) with ``[ax, ay, dr] = A @ C + a0`` (eq. 1 with eq. 2, 4).

    ``ax = dvx - vy r`` and ``ay = dvy + vx r`` are the body accelerations at the CG, ``dr`` the
    yaw acceleration; ``wheel_speed_m_s`` = (front, rear) axle mean ``R_w omega``, m/s (scalars
    or per-particle (N,) arrays). ``saturation_slip_rad`` (front, rear), each (N,), replaces the
    saturation slips of ``p`` per particle (:func:`saturation_slip_at`).
    """
    n = x.shape[0]
    m, iz, lf, lr = p.mass_kg, p.yaw_inertia_kg_m2, p.lf_m, p.lr_m
    cd, sd = np.cos(delta_rad), np.sin(delta_rad)
    alpha_f, alpha_r = slip_angles(x, delta_rad, p)
    # eq. (2) Fy = C alpha, or the saturating C phi(alpha) (lateral_slip_function)
    sat_f, sat_r = (
        (p.saturation_slip_front_rad, p.saturation_slip_rear_rad)
        if saturation_slip_rad is None
        else saturation_slip_rad
    )
    shape = (p.tyre_shape, p.magic_formula_shape_c, p.magic_formula_curvature_e)
    alpha_f = lateral_slip_function(alpha_f, sat_f, *shape)
    alpha_r = lateral_slip_function(alpha_r, sat_r, *shape)
    a = np.zeros((n, 3, 3))
    # eq. (2) F = C * slip; eq. (1) columns = force directions / (m, m, I)
    lam_f = wheel_slip(x[:, 0], wheel_speed_m_s[0]) if p.drive in ("front", "all") else 0.0
    lam_r = wheel_slip(x[:, 0], wheel_speed_m_s[1]) if p.drive in ("rear", "all") else 0.0
    # eq. (1a) m ax = Fxf cos(d) - Fyf sin(d) + Fxr
    a[:, 0, 0] = (lam_f * cd + lam_r) / m
    a[:, 0, 1] = -alpha_f * sd / m
    # eq. (1b) m ay = Fyf cos(d) + Fyr + Fxf sin(d)
    a[:, 1, 0] = lam_f * sd / m
    a[:, 1, 1] = alpha_f * cd / m
    a[:, 1, 2] = alpha_r / m
    # eq. (1c) I dr = lf (Fyf cos(d) + Fxf sin(d)) - lr Fyr
    a[:, 2, 0] = lf * lam_f * sd / iz
    a[:, 2, 1] = lf * alpha_f * cd / iz
    a[:, 2, 2] = -lr * alpha_r / iz
    return a


def resistance_accel(x: F64, p: SingleTrackParams) -> F64:
    """Acceleration ``a0`` (N, 3) of the known resistances (zero under Assumption 4)."""
    a0 = np.zeros_like(x)
    a0[:, 0] = -(p.rolling_resistance_n + p.drag_n_s2_m2 * x[:, 0] * np.abs(x[:, 0])) / p.mass_kg
    return a0


@dataclass(frozen=True)
class Linearized:
    """Affine-in-``w`` model of one step (eq. 9 and eq. 12), per particle.

    With sampling time ``Ts`` the Euler step is ``x_next = f + g w`` with ``f = x + Ts rate``
    and ``g = Ts a`` (eq. 9-10).

    Attributes:
        rate: state derivative with nominal stiffness, (N, 3).
        a: derivative gain of ``w`` (``g / Ts``), (N, 3, 3).
        h: measurement mean with nominal stiffness and no bias, (N, 3).
        d: measurement gain of ``w``, (N, 3, 3); ``y = h + b + d w + e``.
    """

    rate: F64
    a: F64
    h: F64
    d: F64

    def f(self, x: F64, dt_s: float) -> F64:
        """Deterministic next state ``f(x, u)`` (eq. 9), (N, 3)."""
        return x + dt_s * self.rate

    def g(self, dt_s: float) -> F64:
        """Process-noise gain ``g(x, u)`` (eq. 9-10), (N, 3, 3)."""
        return dt_s * self.a


def linearize(
    x: F64,
    delta_rad: float,
    wheel_speed_m_s: tuple[float | F64, float | F64],
    p: SingleTrackParams,
    saturation_slip_rad: tuple[F64, F64] | None = None,
) -> Linearized:
    """Euler-discretized model (eq. 5, 9, 10) and measurement model (eq. 12), see Linearized.

    The measurement is ``y = [ax_imu, ay_imu, r_gyro]`` (specific force at the IMU, roll
    compensated ay, and yaw rate). ``saturation_slip_rad``: per-particle saturation slips, see
    :func:`force_regressor`.
    """
    c_n = np.asarray(p.nominal, dtype=float)
    a = force_regressor(x, delta_rad, wheel_speed_m_s, p, saturation_slip_rad)
    vx, vy, r = x[:, 0], x[:, 1], x[:, 2]
    # eq. (7) accelerations with C = C_n + w -> acc = (A C_n + a0) + A w
    acc_n = np.einsum("nij,j->ni", a, c_n)
    if p.rolling_resistance_n or p.drag_n_s2_m2:
        acc_n += resistance_accel(x, p)
    # eq. (9)-(10) Euler: x_{k+1} = x_k + Ts (acc + kinematic coupling) = f + g w, with the
    # coupling [vY r, -vX r, 0]
    rate = acc_n.copy()
    rate[:, 0] += vy * r
    rate[:, 1] -= vx * r
    # rigid body: a_p = a_cg + dr z x p - r^2 p (IMU at p from the CG)
    px, py = p.imu_x_m, p.imu_y_m
    r2 = r * r
    h = np.empty_like(acc_n)
    h[:, 0] = acc_n[:, 0] - py * acc_n[:, 2] - px * r2
    h[:, 1] = acc_n[:, 1] + px * acc_n[:, 2] - py * r2
    # eq. (12) yaw-rate row: y_r = r + b_r + e_r
    h[:, 2] = r
    # eq. (12) d = [g1; g2; 0] / Ts mapped to the IMU position (d = lever @ a, row by row)
    d = np.empty_like(a)
    d[:, 0, :] = a[:, 0, :] - py * a[:, 2, :]
    d[:, 1, :] = a[:, 1, :] + px * a[:, 2, :]
    d[:, 2, :] = 0.0
    return Linearized(rate=rate, a=a, h=h, d=d)


def kinematic_speed_row(
    lin: Linearized, x: F64, accel_x_m_s2: float, p: SingleTrackParams
) -> Linearized:
    """Row 0 of :func:`linearize` for a measured speed with an unknown longitudinal force.

    Without wheel speeds the slip of eq. (3) is unknown, so ``Fx`` (traction, braking) is not
    modelled; the measured specific force then drives ``vX`` (eq. 1a as kinematics):
    ``dvX/dt = ax_cg + vY r`` with ``ax_cg = ax_imu + dr p_y + r^2 p_x`` (the inverse of the IMU
    lever arm of :func:`linearize`), and the measurement row 0 becomes the measured speed
    ``y_0 = vX + e`` (``d`` row 0 = 0). The ``vY r`` coupling makes ``vY`` observable through
    the speed in turns. Returns a new :class:`Linearized` (rows 1-2 unchanged).
    """
    vx, vy, r = x[:, 0], x[:, 1], x[:, 2]
    px, py = p.imu_x_m, p.imu_y_m
    rate = lin.rate.copy()
    a = lin.a.copy()
    # eq. (1a) kinematics: dvX/dt = ax_cg + vY r, ax_cg = ax_imu + p_y dr + p_x r^2
    rate[:, 0] = accel_x_m_s2 + px * r * r + py * lin.rate[:, 2] + vy * r
    # dr = rate_2 + a_2 w enters through the lever arm p_y (affine in w)
    a[:, 0, :] = py * lin.a[:, 2, :]
    h = lin.h.copy()
    d = lin.d.copy()
    # measurement row 0: y_0 = vX + e
    h[:, 0] = vx
    d[:, 0, :] = 0.0
    return Linearized(rate=rate, a=a, h=h, d=d)


def wheel_speed_gain(
    x: F64,
    delta_rad: float,
    wheel_speed_m_s: tuple[float, float],
    p: SingleTrackParams,
    cx: F64,
) -> F64:
    """Sensitivity of the measurement ``y`` to the driven axles' ``R_w omega``, (N, A, 3).

    ``A`` = 1 (front or rear drive) or 2 (all-wheel drive: front, rear). The slip (eq. 3)
    changes by ``d lambda / d(R_w omega)`` per m/s of wheel speed, the force by ``Cx`` times that
    (eq. 2), and ``y`` by the force column of eq. (1) at the IMU (as in :func:`linearize`).
    ``cx`` is each particle's longitudinal stiffness, (N,). Wheel-speed noise of std ``s``
    therefore adds ``s^2 G^T G`` to the measurement-noise covariance of ``y``.
    """
    n = x.shape[0]
    m, iz, lf = p.mass_kg, p.yaw_inertia_kg_m2, p.lf_m
    cd, sd = np.cos(delta_rad), np.sin(delta_rad)
    px, py = p.imu_x_m, p.imu_y_m
    axles: list[tuple[float, F64]] = []
    if p.drive in ("front", "all"):
        # eq. (1) column of Fxf: [cos d / m, sin d / m, lf sin d / I]
        axles.append((wheel_speed_m_s[0], np.array([cd / m, sd / m, lf * sd / iz])))
    if p.drive in ("rear", "all"):
        # eq. (1) column of Fxr: [1 / m, 0, 0]
        axles.append((wheel_speed_m_s[1], np.array([1.0 / m, 0.0, 0.0])))
    lever = np.array([[1.0, 0.0, -py], [0.0, 1.0, px], [0.0, 0.0, 0.0]])
    out = np.zeros((n, len(axles), 3))
    vx = x[:, 0]
    for j, (rw, col) in enumerate(axles):
        den = np.maximum(np.maximum(vx, rw), MIN_SPEED_M_S)
        # eq. (3) lambda = (R w - vX) / max(vX, R w): d lambda / d(R w) = vX / (R w)^2 when
        # R w is the denominator, else 1 / max(vX, floor)
        dslip = np.where(rw > np.maximum(vx, MIN_SPEED_M_S), vx / (den * den), 1.0 / den)
        out[:, j, :] = (cx * dslip)[:, None] * (lever @ col)[None, :]
    return out


def measurement_cov(
    r_cov: F64,
    x: F64,
    delta_rad: float,
    wheel_speed_m_s: tuple[float, float],
    p: SingleTrackParams,
    cx: F64,
    wheel_speed_std_m_s: float = WHEEL_SPEED_NOISE_STD_M_S,
) -> F64:
    """Measurement-noise covariance of ``y`` per row of ``x``, (N, 3, 3).

    ``R`` (3, 3) of the IMU (eq. 12) plus the wheel-speed noise carried into ``y`` by the slip
    (eq. 2-3): ``s^2 sum_axles g g^T`` with ``g`` from :func:`wheel_speed_gain` at the
    longitudinal stiffness ``cx`` (N,) and ``s`` = ``wheel_speed_std_m_s``.
    """
    s = wheel_speed_std_m_s
    if s <= 0.0 or p.drive not in ("front", "rear", "all"):
        return np.tile(r_cov, (x.shape[0], 1, 1))
    g = wheel_speed_gain(x, delta_rad, wheel_speed_m_s, p, cx)
    # input noise through eq. (2)-(3): Cov = R + s^2 sum_axles g g^T
    outer = g[:, 0, :, None] * g[:, 0, None, :]
    for j in range(1, g.shape[1]):
        outer += g[:, j, :, None] * g[:, j, None, :]
    return r_cov + (s * s) * outer


def stiffness_bounds(nominal: F64) -> tuple[F64, F64]:
    """Bounds of ``w = C - C_n`` (Sec. V projection), (3,) each."""
    return (
        MIN_STIFFNESS_FRACTION * nominal - nominal,
        MAX_STIFFNESS_FRACTION * nominal - nominal,
    )
