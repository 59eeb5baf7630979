"""Sensor agreement: effects sized from the sensors directly, without the filter in between.

The GNSS innovations show an unmodelled effect only through the filter, which absorbs a slowly
varying part of it into its radii and pose. Two of the radius model's relations can be checked
on the raw streams instead, with the radius (and the gyro bias) free per block of
:data:`BLOCK_S`:

* **speed**: the receiver's Doppler ground speed against the rear wheels' mean speed
  ``u = r_n (w_rl + w_rr) / 2`` (nominal radius, after the configured corrections), one row per
  bin of :data:`BIN_S`::

      v_gnss - u = u c_b + d a + k u^3 / r_n + s u b - a_y,ant r + noise

  with ``c_b`` the block's relative radius error, ``a`` the wheels' acceleration (a wheel
  speed stamped ``d`` late reads ``v(t - d) = v - a d``: ``d > 0`` is a wheel-speed time
  offset, ``d < 0`` a velocity latency ``-d``), ``k`` the speed-dependent radius
  ``r = r_0 + k v^2`` (the speed error ``v k v^2 / r_n``), ``s`` the rear brake slip
  (``omega r = v (1 - s b)``, ``b`` the braking deceleration) and ``a_y,ant`` a lateral antenna
  offset (the antenna's along-track speed is ``v - r a_y``, ``r`` the gyro's yaw rate);
* **yaw rate**: the gyro against the rear wheel-speed difference
  ``r_w = r_n (w_rr - w_rl) / l_T``::

      r_gyro - r_w = g_b + u e_b / l_T + c u/r_n 2 dFz / l_T + noise

  with ``g_b`` the block's gyro bias, ``e_b`` its relative left-right radius difference and
  ``c`` the load-dependent radius ``r_i = r_0 + c dFz_i``, the rear lateral load transfer
  ``dFz = m f_y h l_f / (l_T L)`` (Gillespie, Fundamentals of Vehicle Dynamics, ch. 9: roll
  stiffness split like the static loads; ``f_y`` the lateral specific force).

Least squares over the bins while the radii are learned and the rear speed is above
:data:`MIN_SPEED_M_S`, with Newey-West standard errors (:data:`HAC_LAGS` lags: a receiver's
velocity error is correlated over seconds). An effect fails the verdict when its ``|t|`` is at
least the residual analysis' threshold **and** it changes a wheel's speed by at least
:data:`MATERIAL_FRACTION` (RMS over the bins, beyond its mean over a block, which the block's
radius absorbs), the 0.05 % the radii are meant to reach: an effect below it is reported with
its size but does not fail the verdict (the rear brake slip of a car braking gently, about
0.03 %). A lateral antenna offset also fails it from :data:`MATERIAL_LEVER_ARM_M`: whatever it
does to the radii, it moves the published pose. The coefficients are sizes in the
configuration's units,
so the verdict names and sizes an effect in one pass.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core.arrays import F64

#: bin of the agreement record, s (the innovations' decimation, ``residuals.DECIMATION_S``)
BIN_S = 1.0
#: block over which the radius (and the gyro bias) is taken as constant, s
BLOCK_S = 60.0
#: rear-wheel speed below which a bin is not used, m/s (relative errors grow as 1/v)
MIN_SPEED_M_S = 2.0
#: Newey-West lags, bins
HAC_LAGS = 3
#: RMS relative wheel-speed change below which a significant effect does not fail the verdict:
#: the radius accuracy the estimator aims at, 0.05 % (0.15 mm on a 0.31 m tyre)
MATERIAL_FRACTION = 5e-4
#: size of a lateral antenna offset that fails the verdict (when significant) whatever it
#: changes the wheel speeds, m: it moves the published pose across the track by that much, a
#: decimetre being about how well an antenna is placed by hand
MATERIAL_LEVER_ARM_M = 0.1
#: bins with used samples below which a relation is not tested
MIN_BINS = 30

#: columns of a record row
COLUMNS = (
    "t_s",  # bin start since the first bin, s
    "n_all",  # velocity samples in the bin
    "u_all_m_s",  # mean rear speed over all of them (the acceleration)
    "n_used",  # samples used (learning, moving)
    "v_gnss_m_s",  # mean signed Doppler ground speed
    "u_m_s",  # mean rear speed
    "gyro_rad_s",  # mean gyro yaw rate (NaN: no IMU)
    "wheel_yaw_rad_s",  # mean rear wheel-speed yaw rate
    "fy_m_s2",  # mean lateral specific force (NaN: no IMU)
    "brake_m_s2",  # mean braking deceleration
    "locked",  # 1 when the rear axle was locked for any used sample
    "n_fix",  # fixes used (learning, moving)
    "fix_doppler_e_m",  # mean east of the fix minus the integrated Doppler velocity
    "fix_doppler_n_m",  # the same, north
    "fix_v_e_m_s",  # mean Doppler velocity east at the fixes
    "fix_v_n_m_s",  # the same, north
    "segment",  # integration segment of the Doppler velocity (a new one after a gap)
)
_C = {name: i for i, name in enumerate(COLUMNS)}


@dataclass
class AgreementBins:
    """Accumulates the 1-s bins of the agreement record; a finished bin goes to ``rows``.

    Args:
        nominal_radius_m: ``r_n``.
        track_width_m: rear track ``l_T``.
        rows: the finished bins.
        lever_arm_x_m: the antenna's ``base_link`` x (ahead of the rear axle), m.
        sideslip_s2_per_m: ``k = m l_f / (L C_r)``, s^2/m: the rear axle's lateral velocity
            in a steady turn, ``-r k v^2`` (its tyres' slip angle ``m a_y l_f / (L C_r)``).

    In a turn the antenna moves sideways at ``r (a_x - k v^2)`` (``r`` the yaw rate): zero at
    the neutral point ``k v^2`` ahead of the rear axle (0.9 m at 13 m/s, 4.6 m at 30 m/s on a
    mid-size car). The Doppler ground speed holds that sideways part, the wheels do not.
    """

    nominal_radius_m: float
    track_width_m: float
    rows: list[F64] = field(default_factory=list)
    lever_arm_x_m: float = 0.0
    sideslip_s2_per_m: float = 0.0
    _t0_ns: int | None = None
    _bin: int = -1
    _sums: F64 = field(default_factory=lambda: np.zeros(len(COLUMNS)))
    #: Doppler velocity integrated over the current segment (east, north), m
    _doppler_m: F64 = field(default_factory=lambda: np.zeros(2))
    _v_last: tuple[int, float, float] | None = None
    _segment: int = 0

    def _to_bin(self, t_ns: int) -> F64:
        """The sums of the bin of ``t_ns`` (the previous bin closed when it is a new one)."""
        if self._t0_ns is None:
            self._t0_ns = t_ns
        k = (t_ns - self._t0_ns) // round(BIN_S * 1e9)
        if k != self._bin:
            self.flush()
            self._bin = int(k)
        return self._sums

    def _integrate(self, t_ns: int, ve: float, vn: float) -> None:
        """Doppler displacement, trapezoidal; a gap over :data:`BIN_S` starts a new segment."""
        last = self._v_last
        dt = None if last is None else (t_ns - last[0]) * 1e-9
        if last is None or dt is None or not 0.0 < dt <= BIN_S:
            self._segment += 1
            self._doppler_m = np.zeros(2)
        else:
            # D_k = D_{k-1} + (v_k + v_{k-1}) dt / 2
            self._doppler_m += 0.5 * dt * np.array([ve + last[1], vn + last[2]])
        self._v_last = (t_ns, ve, vn)

    def new_segment(self) -> None:
        """Start the integration of the velocity again at the next velocity (the fixes' frame
        changed)."""
        self._v_last = None

    def add_fix(self, t_ns: int, enu_m: tuple[float, float], learning: bool) -> None:
        """One GNSS fix in the estimator's ENU frame: its offset from the integrated Doppler
        velocity (extrapolated from the newest velocity to the fix's stamp)."""
        last = self._v_last
        if last is None or not learning or not 0 <= t_ns - last[0] <= round(BIN_S * 1e9):
            return
        if math.hypot(last[1], last[2]) < MIN_SPEED_M_S:
            return
        s = self._to_bin(t_ns)
        ext = (t_ns - last[0]) * 1e-9
        s[_C["n_fix"]] += 1.0
        s[_C["fix_doppler_e_m"]] += enu_m[0] - (self._doppler_m[0] + last[1] * ext)
        s[_C["fix_doppler_n_m"]] += enu_m[1] - (self._doppler_m[1] + last[2] * ext)
        s[_C["fix_v_e_m_s"]] += last[1]
        s[_C["fix_v_n_m_s"]] += last[2]
        s[_C["segment"]] = self._segment

    def add(
        self,
        t_ns: int,
        velocity_enu_m_s: F64,
        rear_rad_s: tuple[float, float],
        gyro_z_rad_s: float | None,
        lateral_specific_force_m_s2: float | None,
        brake_decel_m_s2: float,
        learning: bool,
        rear_locked: bool,
    ) -> None:
        """One GNSS velocity with the wheel and IMU inputs of its time (a velocity that is not
        finite is left out, and the integration starts again after it)."""
        ve, vn = float(velocity_enu_m_s[0]), float(velocity_enu_m_s[1])
        if not math.isfinite(ve + vn):
            self._v_last = None
            return
        s = self._to_bin(t_ns)
        self._integrate(t_ns, ve, vn)
        w3, w4 = rear_rad_s
        u = 0.5 * self.nominal_radius_m * (w3 + w4)
        s[_C["n_all"]] += 1.0
        s[_C["u_all_m_s"]] += u
        if not learning or abs(u) < MIN_SPEED_M_S:
            return
        # the antenna's along-track speed, signed like the wheels (reverse driving): its
        # velocity in base_link is (v - r a_y, v_y + r a_x), the rear axle's lateral velocity
        # v_y = -r k v^2 in a steady turn (single-track model: v_y = -v alpha_r,
        # alpha_r = m a_y l_f / (L C_r), a_y = r v), so the Doppler ground speed less its
        # sideways part r (a_x - k v^2) (r the gyro's yaw rate, else the rear wheels' with
        # nominal radii)
        yaw = (
            gyro_z_rad_s
            if gyro_z_rad_s is not None
            else self.nominal_radius_m * (w4 - w3) / self.track_width_m
        )
        side = yaw * (self.lever_arm_x_m - self.sideslip_s2_per_m * u * u)
        v = math.sqrt(max(ve * ve + vn * vn - side * side, 0.0))
        s[_C["n_used"]] += 1.0
        s[_C["v_gnss_m_s"]] += math.copysign(v, u)
        s[_C["u_m_s"]] += u
        # rear wheel-speed yaw rate with nominal radii (eq. 6b of the radius paper, delta = 0)
        s[_C["wheel_yaw_rad_s"]] += self.nominal_radius_m * (w4 - w3) / self.track_width_m
        s[_C["gyro_rad_s"]] += math.nan if gyro_z_rad_s is None else gyro_z_rad_s
        s[_C["fy_m_s2"]] += (
            math.nan if lateral_specific_force_m_s2 is None else lateral_specific_force_m_s2
        )
        s[_C["brake_m_s2"]] += brake_decel_m_s2
        s[_C["locked"]] = max(s[_C["locked"]], float(rear_locked))

    def flush(self) -> None:
        """Close the current bin (call after the last sample)."""
        s = self._sums
        if s[_C["n_all"]] > 0:
            row = s.copy()
            row[_C["t_s"]] = self._bin * BIN_S
            row[_C["u_all_m_s"]] /= s[_C["n_all"]]
            n = s[_C["n_used"]]
            for name in COLUMNS[_C["v_gnss_m_s"] : _C["locked"]]:
                row[_C[name]] = row[_C[name]] / n if n > 0 else math.nan
            nf = s[_C["n_fix"]]
            for name in COLUMNS[_C["fix_doppler_e_m"] : _C["segment"]]:
                row[_C[name]] = row[_C[name]] / nf if nf > 0 else math.nan
            self.rows.append(row)
        self._sums = np.zeros(len(COLUMNS))


def _hac_ols(x: F64, y: F64, lags: int = HAC_LAGS) -> tuple[F64, F64]:
    """Least squares ``y = x b`` with Newey-West standard errors (Bartlett weights
    ``1 - l / (lags + 1)``; Newey and West 1987, eq. 2)."""
    b, *_ = np.linalg.lstsq(x, y, rcond=None)
    res = y - x @ b
    xr = x * res[:, None]
    # S = sum_t x_t x_t' e_t^2 + sum_l w_l sum_t (x_t x_{t-l}' e_t e_{t-l} + transpose)
    s = xr.T @ xr
    for lag in range(1, lags + 1):
        g = xr[lag:].T @ xr[:-lag]
        s += (1.0 - lag / (lags + 1.0)) * (g + g.T)
    xtx_inv = np.linalg.pinv(x.T @ x)
    # cov(b) = (X'X)^-1 S (X'X)^-1 (the sandwich)
    cov = xtx_inv @ s @ xtx_inv
    return b, np.sqrt(np.maximum(np.diag(cov), 1e-300))


def _blocks(t_s: F64, per: F64 | None = None) -> list[F64]:
    """One column per :data:`BLOCK_S` block: the block's indicator (times ``per``)."""
    blk = np.floor(t_s / BLOCK_S).astype(int)
    cols = []
    for j in np.unique(blk):
        ind = (blk == j).astype(float)
        cols.append(ind if per is None else ind * per)
    return cols


def _entry(
    b: float,
    se: float,
    relative: F64,
    t_s: F64,
    score_threshold: float,
    material_size: float = math.inf,
) -> dict[str, Any]:
    """Size, t statistic and RMS relative wheel-speed change of one fitted effect
    (``relative``: its relative speed change per bin; the part constant over a block is taken
    out, since the block's radius absorbs it). A significant effect matters when that change
    reaches :data:`MATERIAL_FRACTION` or its size ``|b|`` reaches ``material_size``."""
    blk = np.floor(t_s / BLOCK_S).astype(int)
    _, inv, counts = np.unique(blk, return_inverse=True, return_counts=True)
    dev = relative - (np.bincount(inv, relative) / counts)[inv]
    rel = float(np.sqrt(np.mean(dev**2)))
    t = b / se
    return {
        "estimate": float(b),
        "t": float(t),
        "relative_rms": rel,
        "significant": bool(
            abs(t) >= score_threshold and (rel >= MATERIAL_FRACTION or abs(b) >= material_size)
        ),
    }


def analyze(
    rows: NDArray[np.float64],
    params: dict[str, float],
    score_threshold: float,
) -> dict[str, Any]:
    """The two relations fitted over a record (:class:`AgreementBins` rows, (K, 11)).

    ``params``: ``nominal_radius_m``, ``track_width_m``, ``mass_kg``, ``cg_height_m``,
    ``cg_to_front_axle_m``, ``wheelbase_m``, and the configured ``velocity_shift_s`` (the
    wheel time at which the estimator reads a velocity, ``t + shift``) and ``lever_arm_y_m``.
    Returns ``{"speed": {...}, "yaw_rate": {...}}``, each with ``bins`` and per effect (by the
    name of :mod:`~tire_estimation.core.radius.effects`) its ``estimate``, ``t``,
    ``relative_rms`` and ``significant``; ``{"note": ...}`` for a relation not tested.
    """
    out: dict[str, Any] = {}
    if rows.ndim != 2 or rows.shape[0] < 3:
        note = {"note": "no GNSS velocity record"}
        return {"speed": note, "yaw_rate": note}
    col = {name: rows[:, i] for i, name in enumerate(COLUMNS)}
    rn = params["nominal_radius_m"]
    # the wheels' acceleration from all samples of neighbouring bins (central differences)
    accel = np.gradient(col["u_all_m_s"], col["t_s"])
    n_used = col["n_used"]
    full = n_used >= 0.8 * max(float(np.max(col["n_all"])), 1.0)
    out["speed"] = _speed(col, accel, full, rn, params, score_threshold)
    out["yaw_rate"] = _yaw(col, full, rn, params, score_threshold)
    out["position"] = _position(col, accel, params, out["speed"], score_threshold)
    return out


def _speed(
    col: dict[str, F64],
    accel: F64,
    full: NDArray[np.bool_],
    rn: float,
    params: dict[str, float],
    score_threshold: float,
) -> dict[str, Any]:
    ok = full & np.isfinite(col["v_gnss_m_s"])
    gyro_ok = bool(np.all(np.isfinite(col["gyro_rad_s"][ok])))
    n = int(ok.sum())
    if n < MIN_BINS:
        return {"bins": n, "note": "too few bins while learning with a GNSS velocity"}
    t, u, a = col["t_s"][ok], col["u_m_s"][ok], accel[ok]
    # the configured alignment and lever arm (the estimator's own model): the wheels at
    # t + shift, the antenna's along-track speed v - r a_y
    u_model = u + a * params["velocity_shift_s"]
    v = col["v_gnss_m_s"][ok]
    regs: dict[str, F64] = {
        # v(t) - v(t - d) = a d: a positive slope is a wheel-speed time offset, a negative one
        # a velocity latency
        "time_alignment": a,
        # r = r_0 + k v^2 -> speed error k v^3 / r_n
        "radius_speed_dependence": u**3 / rn,
        # omega r = v (1 - s b) -> v - omega r = s v b
        "rear_brake_slip": u * col["brake_m_s2"][ok],
    }
    if gyro_ok:
        r = col["gyro_rad_s"][ok]
        v = v + r * params["lever_arm_y_m"]
        # antenna along-track speed v - r a_y -> slope -a_y on r
        regs["gnss_lever_arm_y"] = -r
    names = [k for k, x in regs.items() if np.std(x) > 1e-9 * max(1.0, np.max(np.abs(x)))]
    blocks = _blocks(t, per=u)
    x = np.column_stack(blocks + [regs[k] for k in names])
    b, se = _hac_ols(x, v - u_model)
    nb = len(blocks)
    res: dict[str, Any] = {"bins": n}
    for i, name in enumerate(names):
        j = nb + i
        size = MATERIAL_LEVER_ARM_M if name == "gnss_lever_arm_y" else math.inf
        res[name] = _entry(b[j], se[j], b[j] * regs[name] / u, t, score_threshold, size)
    return res


def _position(
    col: dict[str, F64],
    accel: F64,
    params: dict[str, float],
    speed: dict[str, Any],
    score_threshold: float,
) -> dict[str, Any]:
    n_fix = col["n_fix"]
    ok = (n_fix >= 0.8 * max(float(np.max(n_fix)), 1.0)) & np.isfinite(col["fix_doppler_e_m"])
    n = int(ok.sum())
    if n < MIN_BINS:
        return {"bins": n, "note": "too few bins with fixes and a GNSS velocity while learning"}
    t, seg = col["t_s"][ok], col["segment"][ok]
    ve, vn = col["fix_v_e_m_s"][ok], col["fix_v_n_m_s"][ok]
    # the estimator compares a fix stamped t with the pose at t + fix_shift and a velocity
    # with the wheels at t + velocity_shift: the fix leads the integrated velocity by
    # v (fix_shift - velocity_shift) as configured; what is left is c_p v
    rel_s = params["fix_shift_s"] - params["velocity_shift_s"]
    y = np.concatenate(
        [col["fix_doppler_e_m"][ok] - ve * rel_s, col["fix_doppler_n_m"][ok] - vn * rel_s]
    )
    # per block of a segment: an offset and a drift per axis (the fix's slowly varying error)
    key = seg * 1e6 + np.floor(t / BLOCK_S)
    zero = np.zeros(n)
    cols = []
    for j in np.unique(key):
        ind = (key == j).astype(float)
        drift = (t - t[key == j].mean()) * ind
        for c in (ind, drift):
            cols += [np.concatenate([c, zero]), np.concatenate([zero, c])]
    x = np.column_stack([*cols, np.concatenate([ve, vn])])
    b, se = _hac_ols(x, y)
    c_p, se_p = float(b[-1]), float(se[-1])
    # undeclared fix shift c_p + c_s against the wheels, c_s the velocity's (the speed
    # relation); the part of c_s that is a velocity latency (c_s < 0) moves the velocity, not
    # the fixes, so it is taken back: fix latency = -(c_p + min(c_s, 0))
    latency, se_l = -c_p, se_p
    fit = speed.get("time_alignment")
    if isinstance(fit, dict) and fit["estimate"] < 0.0 and fit["t"] != 0.0:
        latency = -(c_p + fit["estimate"])
        se_l = math.hypot(se_p, fit["estimate"] / fit["t"])
    speed_m_s = np.maximum(np.hypot(ve, vn), MIN_SPEED_M_S)
    a = accel[ok]
    return {
        "bins": n,
        "fix_vs_velocity_s": c_p,
        # a fix latency tau reads the position of t - tau: a speed error -a tau
        "gnss_latency": _entry(latency, se_l, latency * a / speed_m_s, t, score_threshold),
    }


def _yaw(
    col: dict[str, F64],
    full: NDArray[np.bool_],
    rn: float,
    params: dict[str, float],
    score_threshold: float,
) -> dict[str, Any]:
    ok = (
        full & np.isfinite(col["gyro_rad_s"]) & np.isfinite(col["fy_m_s2"]) & (col["locked"] < 0.5)
    )
    n = int(ok.sum())
    if n < MIN_BINS:
        return {"bins": n, "note": "too few bins with a fresh IMU on a free rear axle"}
    t, u = col["t_s"][ok], col["u_m_s"][ok]
    lt = params["track_width_m"]
    # rear load transfer per unit lateral specific force, N s^2/m (the load dependence's
    # regressor, as the estimator's correction: m h l_f / (l_T L))
    per_fy = (
        params["mass_kg"]
        * params["cg_height_m"]
        * params["cg_to_front_axle_m"]
        / (lt * params["wheelbase_m"])
    )
    # yaw-rate error of the radius difference 2 c dFz: (u / r_n) 2 c dFz / l_T
    x_load = u / rn * 2.0 * per_fy * col["fy_m_s2"][ok] / lt
    if np.std(x_load) <= 1e-12:
        return {"bins": n, "note": "no lateral acceleration"}
    cols = _blocks(t) + _blocks(t, per=u / lt) + [x_load]
    y = col["gyro_rad_s"][ok] - col["wheel_yaw_rad_s"][ok]
    b, se = _hac_ols(np.column_stack(cols), y)
    # relative speed change of each rear wheel, c dFz / r_n = (yaw error) l_T / (2 u)
    return {
        "bins": n,
        "radius_load_dependence": _entry(
            b[-1], se[-1], b[-1] * x_load * lt / (2.0 * u), t, score_threshold
        ),
    }
