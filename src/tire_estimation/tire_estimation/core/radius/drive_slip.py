"""Traction slip of driven rear wheels, learned against the free-rolling front axle.

Lundquist et al. (T-ITS 2014, Sec. II) learn the rolling radius of free-rolling rear wheels;
driven wheels, they note (Sec. IV), would need their slip compensated. A wheel that drives the
car turns faster than it rolls: ``omega r = v (1 + kappa)`` with the longitudinal slip
``kappa = F_x / C_x`` of its share ``F_x`` of the traction force (small slip: the slip-slope
model of Gustafsson, Automatica 33(6), 1997). The rear radii of a rear-driven car absorb the
mean slip: about ``-r F / C_x``, -1.1 to -1.6 mm (z -11 to -16) on
the simulator's car made rear-driven, 10-min drives at 40-120 km/h.

Model of the rear slip (traction force per unit mass ``a + c_rr g + rho C_d A v^2 / (2 m)``
over the axle's slip stiffness ``C_x``):

    kappa = c1 (a + c_rr g) + c2 v^2,   c1 = m / C_x,   c2 = rho C_d A / (2 C_x)

with ``a = dv/dt + g sin(grade)`` the acceleration the powertrain supplies. On straight driving
without braking the front wheels roll freely, so the ratio of the rear to the front wheel speeds
is

    q = omega_r / omega_f - 1 = (r_f / r_r) (1 + kappa) - 1 = b0 + c1' a + c2' v^2

(``b0 = r_f / r_r - 1 + c1' c_rr g``, the slopes scaled by ``r_f / r_r``, 1 within a
percent): ``c1`` and ``c2`` are the slopes of a linear regression of ``q`` on ``a`` and ``v^2``
over 2-s bins, with exponential forgetting and a prior from ``vehicle.yaml``
(``mass_kg / longitudinal_stiffness_rear_n``; a typical drag area). The bin's acceleration comes
from the front wheels' speed at its ends; its noise, which would shrink the slope, is taken out
(corrected least squares), and the slope is learned only where the acceleration varied enough
to tell it (a steady cruise keeps the prior). The rolling-resistance part ``c1 c_rr g`` stays
in the intercept with the radius ratio and is taken with
:data:`ROLLING_RESISTANCE_COEFFICIENT`; its uncertainty and the coefficients' are added to the
reported std of the radii (:meth:`DriveSlip.radius_variance_m2`). A car driven on all wheels
has no free axle: its slip is corrected with the prior and reported as not learned. A car said
to be front-driven is only watched: its driven front wheels make the slope negative; a slope
positive by :data:`DETECT_SIGMAS` standard errors is rear wheels that slip (vehicle.yaml's
``drive`` is wrong), which switches the correction on and is reported. Braking (a negative
traction force) is not corrected: the brake balance is unknown, as for a front-driven car's
rear wheels.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.radius.model import FL, FR, RL, RR
from tire_estimation.core.vehicle import VehicleParams

#: standard gravity, m/s^2
GRAVITY_M_S2 = 9.80665

#: rolling-resistance coefficient ``c_rr`` assumed for the constant part of the slip (radial
#: passenger-car tyre on asphalt, 0.008-0.015; the simulator's 0.012)
ROLLING_RESISTANCE_COEFFICIENT = 0.012

#: its uncertainty (one std), carried into the reported std of the radii
ROLLING_RESISTANCE_STD = 0.003

#: drag area ``C_d A`` of the prior of ``c2``, m^2 (passenger car), and the air density, kg/m^3
PRIOR_DRAG_AREA_M2 = 0.7
AIR_DENSITY_KG_M3 = 1.2

#: length of a regression bin, s; memory of the regression (exponential forgetting), s
BIN_S = 2.0
MEMORY_S = 600.0

#: bins needed (forgetting-weighted) before the regression replaces the prior
MIN_BINS = 20.0

#: speeds averaged for the speed at each end of a bin
EDGE_SAMPLES = 20

#: the slope is learned once the data alone give it to this share of its size (or the prior's)
MAX_SLOPE_STD_SHARE = 0.25

#: a car said to be front-driven is taken for rear-driven when the slope is positive by this many
#: of its standard errors
DETECT_SIGMAS = 5.0

#: the acceleration's spread must be at least this share signal, not wheel-speed noise, for the
#: slope to be learned (the reliability ratio of the regressor; Fuller, Measurement Error
#: Models, 1987)
MIN_RELIABILITY = 0.5

#: a bin is used when the front wheels roll above this speed, m/s, the path is this straight
#: (|yaw rate / speed|, 1/m) and the car does not brake (a above this, m/s^2)
MIN_SPEED_M_S = 5.0
MAX_CURVATURE_1_M = 0.002
MIN_ACCEL_M_S2 = -0.1
MAX_ACCEL_M_S2 = 3.0

#: time constant of each stage of the low-passed acceleration of the correction, s (the slip
#: follows the acceleration about 2 tau late; its noise, clipped at 0, would bias it)
ACCEL_TIME_CONSTANT_S = 0.5

#: the applied slip is clipped to [0, this] (beyond it the wheel spins)
MAX_SLIP = 0.05


class DriveSlip:
    """Learns and removes the traction slip of driven rear wheels (module docstring).

    Args:
        vehicle: ``drive``, ``mass_kg``, the longitudinal stiffnesses, ``track_width_m``.
    """

    def __init__(self, vehicle: VehicleParams) -> None:
        self.drive = vehicle.drive
        #: whether the rear wheels are driven (the correction is applied)
        self.enabled = vehicle.drive in ("rear", "all")
        #: whether the regression runs: a rear-driven car learns its slip against the free front
        #: wheels; a car said to be front-driven is watched for rear wheels that slip
        self.learnable = vehicle.drive in ("rear", "front")
        #: whether a car said to be front-driven showed driven rear wheels (then corrected)
        self.detected = False
        c_x = vehicle.longitudinal_stiffness_rear_n
        if vehicle.drive == "all":
            # equal slip on both axles: the force splits like the stiffnesses
            c_x += vehicle.longitudinal_stiffness_front_n
        self._radius_m = vehicle.nominal_tire_radius_m
        self._track_m = vehicle.track_width_m
        # prior slopes: c1 = m / C_x, c2 = rho C_d A / (2 C_x)
        self.prior = (vehicle.mass_kg / c_x, 0.5 * AIR_DENSITY_KG_M3 * PRIOR_DRAG_AREA_M2 / c_x)
        #: slip per unit acceleration c1 (s^2/m) and per unit speed squared c2 (s^2/m^2) in use
        self.coefficients = self.prior
        #: their posterior std (the prior's while not learned)
        self.coefficient_std = self.prior
        #: whether the coefficients in use come from the regression
        self.learned = False
        #: forgetting-weighted number of bins in the regression
        self.bins = 0.0
        self._lam = math.exp(-BIN_S / MEMORY_S)
        self._info = np.zeros((3, 3))
        self._vec = np.zeros(3)
        self._yy = 0.0
        self._noise_aa = 0.0
        #: the share of the acceleration's spread that is not wheel-speed noise (0 until
        #: MIN_BINS bins); below MIN_RELIABILITY the slopes are not updated
        self.reliability = 0.0
        self._t_ns: int | None = None
        self._v1 = 0.0
        self._v2 = 0.0
        self._front_prev = False
        self._slip_sum = 0.0
        self._slip_n = 0
        #: the latest speeds (time s, speed m/s) and the mean of those at the last bin's end
        self._edge: deque[tuple[float, float]] = deque(maxlen=EDGE_SAMPLES)
        self._edge_prev: tuple[float, float] | None = None
        #: (usable, q, v^2, yaw rate) of the latest samples, half an edge window long
        self._delay: deque[tuple[bool, float, float, float]] = deque(maxlen=EDGE_SAMPLES // 2 + 1)
        self._bin_reset(None)

    @property
    def mean_slip(self) -> float:
        """Mean slip removed from the rear wheel speeds so far, 1."""
        return self._slip_sum / self._slip_n if self._slip_n else 0.0

    def correct(
        self, t_ns: int, ws: F64, grade_rad: float, max_gap_s: float, front_measured: bool
    ) -> F64:
        """The wheel speeds ``ws`` (fl, fr, rl, rr) rad/s with the rear wheels' slip removed
        (``omega / (1 + kappa)``); learns from the sample first when the front axle is free and
        ``front_measured`` (not filled in from the rear wheels)."""
        if not (self.enabled or self.learnable):
            return ws
        w = ws.tolist()
        if not (math.isfinite(w[RL]) and math.isfinite(w[RR])):
            return ws
        r = self._radius_m
        front = front_measured and math.isfinite(w[FL] + w[FR])
        # the speed and acceleration from the free-rolling front wheels when they are reported:
        # the rear wheels' own, v (1 + kappa), change with the slip (v d kappa / dt, 0.04 m/s^2
        # at 26 m/s and a jerk of 0.15 m/s^3), which would bias the regression
        v = 0.5 * r * (w[FL] + w[FR] if front and self.learnable else w[RL] + w[RR])
        dt = 0.0 if self._t_ns is None else (t_ns - self._t_ns) * 1e-9
        self._t_ns = t_ns
        if 0.0 < dt <= max_gap_s and front == self._front_prev:
            # two first-order low-passes in cascade; their difference over the time constant
            # is the low-passed derivative (a ramp a t: each stage lags by a tau), with a noise
            # of about sigma_v sqrt(dt / (4 tau^3)) (0.006 m/s^2 for 0.04 m/s at 100 Hz)
            k = dt / (ACCEL_TIME_CONSTANT_S + dt)
            self._v1 += k * (v - self._v1)
            self._v2 += k * (self._v1 - self._v2)
        else:
            self._v1 = self._v2 = v
            if not 0.0 < dt <= max_gap_s:
                self._bin_reset(None)
                self._edge.clear()
                self._delay.clear()
        accel = (self._v1 - self._v2) / ACCEL_TIME_CONSTANT_S
        self._front_prev = front
        g_sin = GRAVITY_M_S2 * math.sin(grade_rad)
        if self.learnable and front:
            self._learn(t_ns, w, v)
        if not self.enabled:
            return ws
        c1, c2 = self.coefficients
        # kappa = c1 (a + c_rr g) + c2 v^2 (module docstring: the slip slope, Gustafsson 1997)
        kappa = c1 * (accel + g_sin + ROLLING_RESISTANCE_COEFFICIENT * GRAVITY_M_S2)
        # a negative traction force is braking: the brakes share it with the front axle in a
        # proportion nothing here tells (the rear brake slip is an effect of its own,
        # ``rear_brake_slip_s2_per_m``), so only the driving slip is taken out
        kappa = max(0.0, min(MAX_SLIP, kappa + c2 * v * v))
        self._slip_sum += kappa
        self._slip_n += 1
        out = ws.copy()
        # driven wheel: omega r = v (1 + kappa)  ->  rolling speed omega / (1 + kappa)
        out[RL:] /= 1.0 + kappa
        return out

    # ------------------------------------------------------------------ regression
    def _bin_reset(self, t_ns: int | None) -> None:
        self._bin_t0 = t_ns
        self._bin_n = 0
        self._bin_q = 0.0
        self._bin_v2 = 0.0
        self._bin_yaw = 0.0
        self._bin_ok = True
        self._bin_d2 = 0.0
        self._bin_d2_n = 0

    def _learn(self, t_ns: int, w: list[float], v: float) -> None:
        wf = 0.5 * (w[FL] + w[FR])
        wr = 0.5 * (w[RL] + w[RR])
        ok = wf * self._radius_m > MIN_SPEED_M_S and wr > 0.0
        edge_buf = self._edge
        if len(edge_buf) >= 2:
            # second difference of the speed: 6 sigma^2 for white noise (the acceleration's
            # change over two samples is far below it)
            d2 = v - 2.0 * edge_buf[-1][1] + edge_buf[-2][1]
            self._bin_d2 += d2 * d2
            self._bin_d2_n += 1
        edge_buf.append((t_ns * 1e-9, v))
        if self._bin_t0 is None:
            self._bin_reset(t_ns)
            self._edge_prev = None
            self._delay.clear()
        # eq. (4b) of the radius paper: yaw rate from the rear wheel-speed difference
        yaw = (w[RR] - w[RL]) * self._radius_m / self._track_m
        self._delay.append((ok, wr / wf - 1.0 if ok else 0.0, v * v, yaw))
        if len(self._delay) == self._delay.maxlen:
            # the bins take each sample half an edge window late, so that q's window lies
            # between the centres of the end speeds' windows (else the acceleration lags q)
            ok_d, q, v2, yaw_d = self._delay.popleft()
            self._bin_ok = self._bin_ok and ok_d
            if ok_d:
                self._bin_n += 1
                self._bin_q += q
                self._bin_v2 += v2
                self._bin_yaw += yaw_d
        t0 = self._bin_t0
        assert t0 is not None
        if (t_ns - t0) * 1e-9 < BIN_S:
            return
        # the bin's mean acceleration is its end speed less its start speed over its length
        # (a mean over other windows would smooth it unlike q); each end speed is the mean of
        # the last EDGE_SAMPLES speeds, so that the wheel-speed noise does not shrink the slope
        # (errors in variables)
        edge = (
            sum(t for t, _ in self._edge) / len(self._edge),
            sum(x for _, x in self._edge) / len(self._edge),
        )
        prev, self._edge_prev = self._edge_prev, edge
        n = self._bin_n
        if prev is not None and self._bin_ok and n > 1:
            v_mean = math.sqrt(self._bin_v2 / n)
            # the regressor leaves the grade out: the online grade is noisy on the scale of
            # the slope's signal (0.1 m/s^2 and more), and the traction of a climb, missing,
            # is noise uncorrelated with the acceleration
            span = edge[0] - prev[0]
            a = (edge[1] - prev[1]) / span
            # its noise: two end speeds, each a mean of EDGE_SAMPLES samples
            sigma2 = self._bin_d2 / (6.0 * max(self._bin_d2_n, 1))
            noise_a = 2.0 * sigma2 / len(self._edge) / span**2
            if (
                abs(self._bin_yaw) < MAX_CURVATURE_1_M * v_mean * n
                and MIN_ACCEL_M_S2 < a < MAX_ACCEL_M_S2
            ):
                self._add(a, self._bin_v2 / n, self._bin_q / n, noise_a)
        self._bin_reset(t_ns)

    def _add(self, a: float, v2: float, q: float, noise_a: float) -> None:
        """One bin into the forgetting-weighted least squares of ``q`` on ``[1, a, v^2]``;
        ``noise_a`` is the variance of the noise in ``a``, (m/s^2)^2."""
        x = np.array([1.0, a, v2])
        lam = self._lam
        self._info = lam * self._info + np.outer(x, x)
        self._vec = lam * self._vec + q * x
        self._yy = lam * self._yy + q * q
        self._noise_aa = lam * self._noise_aa + noise_a
        self.bins = lam * self.bins + 1.0
        if self.bins < MIN_BINS:
            return
        info = self._info
        # spread of the acceleration about its mean, and the share of it that is noise
        s_aa = info[1, 1] - info[0, 1] ** 2 / info[0, 0]
        self.reliability = 1.0 - self._noise_aa / s_aa if s_aa > 0.0 else 0.0
        if self.reliability < MIN_RELIABILITY:
            return
        # corrected least squares for a regressor with known error variance (Fuller 1987):
        # the noise variance of the acceleration taken out of its sum of squares
        corrected = info.copy()
        corrected[1, 1] -= self._noise_aa
        try:
            beta = np.linalg.solve(corrected, self._vec)
        except np.linalg.LinAlgError:
            return
        # residual variance of a bin: (q'q - 2 beta'b + beta'A beta) / (n - 3)
        rss = max(self._yy - 2.0 * float(self._vec @ beta) + float(beta @ info @ beta), 0.0)
        var = max(rss / max(self.bins - 3.0, 1.0), 1e-14)
        try:
            data_cov = np.linalg.inv(corrected / var)
        except np.linalg.LinAlgError:
            return
        # the data must pin the slope down (a steady cruise does not, whatever its length)
        if data_cov[1, 1] <= 0.0 or math.sqrt(data_cov[1, 1]) > MAX_SLOPE_STD_SHARE * max(
            self.prior[0], abs(float(beta[1]))
        ):
            return
        if not self.enabled:
            # said to be front-driven: the front wheels' slip makes the slope negative; a
            # positive one is the rear wheels slipping (vehicle.yaml's drive is wrong)
            if float(beta[1]) < DETECT_SIGMAS * math.sqrt(data_cov[1, 1]):
                return
            self.enabled = self.detected = True
        # posterior with the prior on the slopes (std = the prior value itself) and a flat
        # intercept: (A / s^2 + P) beta = b / s^2 + P beta_0
        p1, p2 = self.prior
        prior_info = np.diag([0.0, 1.0 / p1**2, 1.0 / p2**2])
        post = corrected / var + prior_info
        rhs = self._vec / var + prior_info @ np.array([0.0, p1, p2])
        try:
            cov = np.linalg.inv(post)
        except np.linalg.LinAlgError:
            return
        beta = cov @ rhs
        self.coefficients = (float(beta[1]), float(beta[2]))
        self.coefficient_std = (math.sqrt(cov[1, 1]), math.sqrt(cov[2, 2]))
        self.learned = True

    def radius_variance_m2(self) -> float:
        """What the slip model adds to the variance of each rear radius (fully correlated
        between the two), m^2: the slip removed so far times the relative std of the
        coefficients (1 for the prior), and the rolling-resistance part's
        ``c1 g std(c_rr)``."""
        if not self.enabled:
            return 0.0
        c1, c2 = self.coefficients
        s1, s2 = self.coefficient_std
        rel = min(1.0, max(s1 / max(abs(c1), 1e-12), s2 / max(abs(c2), 1e-15)))
        slip_var = (self.mean_slip * rel) ** 2 + (c1 * GRAVITY_M_S2 * ROLLING_RESISTANCE_STD) ** 2
        return self._radius_m**2 * slip_var

    def summary(self) -> dict[str, object]:
        """What the correction did, for ``metrics.json``."""
        source = "learned" if self.learned else "prior" if self.enabled else "off"
        return {
            "drive": self.drive,
            "detected": self.detected,
            "source": source,
            "slip_per_accel_s2_per_m": self.coefficients[0],
            "slip_per_speed2_s2_per_m2": self.coefficients[1],
            "std": list(self.coefficient_std),
            "bins": self.bins,
            "reliability": self.reliability,
            "mean_slip": self.mean_slip,
        }
