"""Wheel odometry corrected with the learned radii: effective radii and multipliers, the twist
covariance, the wheel-speed noise, and dead reckoning with the corrected twist of a simulated
drive against dead reckoning with the nominal radius."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tire_estimation.core.pipeline import (
    EstimationPipeline,
    PipelineConfig,
    RadiiOutput,
    WheelOdometryOutput,
)
from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.radius.estimator import RadiusEstimator
from tire_estimation.core.radius.report import RadiusEstimate
from tire_estimation.core.radius.wheel_odometry import (
    NOISE_AVERAGING_SAMPLES,
    SPEED_VAR_FLOOR_M2_S2,
    YAW_RATE_VAR_FLOOR_RAD2_S2,
    WheelSpeedNoise,
    corrected_twist,
    effective_radii,
    estimate_radii,
)
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import InputError
from tire_estimation.sim import simulate
from tire_estimation.sources import sim_samples

VEH = VehicleParams(name="test_car", nominal_tire_radius_m=0.3, track_width_m=1.5)


def _estimate(
    radius_error_m: list[float],
    cov_m2: np.ndarray | None,
    speed_m_s: float,
    yaw_rate_rad_s: float,
    std_m: list[float] | None = None,
) -> RadiusEstimate:
    """A rear-wheel estimate whose speed and yaw rate are eq. (6) of its radii."""
    if std_m is None:
        assert cov_m2 is not None
        std_m = np.sqrt(np.diag(cov_m2)).tolist()
    return RadiusEstimate(
        t_ns=123,
        wheels=("wheel_rl", "wheel_rr"),
        radius_error_m=np.array(radius_error_m),
        radius_error_std_m=np.array(std_m),
        radius_noise_std_m=np.array([1e-3, 1e-3]),
        active=(True, True),
        pose=np.zeros(3),
        pose_cov=np.eye(3),
        speed_m_s=speed_m_s,
        yaw_rate_rad_s=yaw_rate_rad_s,
        n_eff=100.0,
        resample_count=0,
        state="running",
        state_reason="",
        rear_radius_error_cov_m2=cov_m2,
    )


def test_effective_radii_multipliers_and_speed_scale_factor() -> None:
    radii = effective_radii(
        ("wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr"),
        [0.0, 1e-3, -3e-3, 6e-3],
        [1e-4, 1e-4, 2e-4, -2e-4],
        0.3,
    )
    np.testing.assert_allclose(radii.radius_m, [0.3, 0.301, 0.297, 0.306])
    np.testing.assert_allclose(radii.multiplier, [1.0, 0.301 / 0.3, 0.99, 1.02])
    np.testing.assert_allclose(radii.radius_std_m, [1e-4, 1e-4, 2e-4, 2e-4])
    # mean rear radius over nominal: (0.297 + 0.306) / 2 / 0.3
    assert radii.speed_scale_factor == pytest.approx(1.005)
    assert radii.of("wheel_rr") == pytest.approx((0.306, 1.02))


@pytest.mark.parametrize(
    ("wheels", "err", "std", "nominal", "match"),
    [
        (("wheel_rl", "wheel_rr"), [0.0], [0.0, 0.0], 0.3, "2 wheels but 1 errors"),
        (("wheel_fl", "wheel_rl"), [0.0, 0.0], [0.0, 0.0], 0.3, "no radius of wheel_rr"),
        (("wheel_rl", "wheel_rr"), [math.nan, 0.0], [0.0, 0.0], 0.3, "not finite"),
        (("wheel_rl", "wheel_rr"), [0.0, -0.4], [0.0, 0.0], 0.3, "wheel_rr is not positive"),
        (("wheel_rl", "wheel_rr"), [0.0, 0.0], [0.0, 0.0], 0.0, "nominal radius"),
    ],
)
def test_effective_radii_reject_what_gives_no_radius(
    wheels: tuple[str, ...], err: list[float], std: list[float], nominal: float, match: str
) -> None:
    with pytest.raises(InputError, match=match) as info:
        effective_radii(wheels, err, std, nominal)
    assert info.value.kind == "radii"


def test_twist_covariance_is_the_propagated_radius_and_wheel_speed_uncertainty() -> None:
    """The (vx, yaw rate) covariance against a Monte Carlo of eq. (6) with radius errors drawn
    from their posterior and wheel speeds with the given noise."""
    d = np.array([2e-3, -1e-3])
    p = np.array([[4e-7, 3e-7], [3e-7, 5e-7]])  # correlated, as a straight drive leaves them
    omega = np.array([60.0, 62.0])
    radii = VEH.nominal_tire_radius_m + d
    lt = VEH.track_width_m
    vx = 0.5 * float(omega @ radii)
    yr = float(omega[1] * radii[1] - omega[0] * radii[0]) / lt
    noise = (0.04, 0.09)
    tw = corrected_twist(_estimate(d.tolist(), p, vx, yr), VEH, noise)
    assert (tw.t_ns, tw.vx_m_s, tw.yaw_rate_rad_s) == (123, vx, yr)

    rng = np.random.default_rng(7)
    n = 400_000
    dd = rng.multivariate_normal(np.zeros(2), p, n)  # error of the learned radii
    ww = omega + rng.standard_normal((n, 2)) * np.sqrt(noise)
    rr = radii + dd
    v_mc = 0.5 * (ww[:, 0] * rr[:, 0] + ww[:, 1] * rr[:, 1])
    y_mc = (ww[:, 1] * rr[:, 1] - ww[:, 0] * rr[:, 0]) / lt
    np.testing.assert_allclose(tw.covariance, np.cov(v_mc, y_mc), rtol=0.02)
    # the correlation of the radius errors matters: without it the yaw-rate variance differs
    uncorrelated = corrected_twist(_estimate(d.tolist(), np.diag(np.diag(p)), vx, yr), VEH, noise)
    assert uncorrelated.covariance[1, 1] > 1.1 * tw.covariance[1, 1]
    # no covariance in the estimate: the stds, uncorrelated
    from_std = corrected_twist(
        _estimate(d.tolist(), None, vx, yr, std_m=np.sqrt(np.diag(p)).tolist()), VEH, noise
    )
    np.testing.assert_allclose(from_std.covariance, uncorrelated.covariance, rtol=1e-12)


def test_twist_variances_have_floors_at_standstill() -> None:
    tw = corrected_twist(_estimate([1e-3, 1e-3], np.eye(2) * 1e-6, 0.0, 0.0), VEH)
    assert tw.covariance[0, 0] == SPEED_VAR_FLOOR_M2_S2
    assert tw.covariance[1, 1] == YAW_RATE_VAR_FLOOR_RAD2_S2
    assert tw.covariance[0, 1] == 0.0


def test_the_radius_estimate_carries_the_rear_covariance_its_stds_come_from() -> None:
    est = RadiusEstimator(
        RadiusEstimatorConfig(n_particles=50), VEH, np.random.default_rng(0)
    ).estimate()
    cov = est.rear_radius_error_cov_m2
    assert cov is not None and cov.shape == (2, 2)
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), est.radius_error_std_m[-2:], rtol=1e-12)
    radii = estimate_radii(est, VEH)
    np.testing.assert_allclose(radii.radius_m, VEH.nominal_tire_radius_m)  # the prior
    assert radii.speed_scale_factor == 1.0


def test_wheel_speed_noise_is_measured_on_the_wheel_speeds() -> None:
    rng = np.random.default_rng(3)
    noise = WheelSpeedNoise()
    assert noise.var_rad2_s2 == (0.0, 0.0)
    sigma = (0.2, 0.05)
    t = np.arange(2000) * 10_000_000
    # accelerating and turning: smooth motion leaves the second difference
    base = 20.0 + 2.0 * np.sin(t * 1e-9) + 0.05 * (t * 1e-9) ** 2
    for k, t_ns in enumerate(t.tolist()):
        w = np.array([0.0, 0.0, base[k], 1.05 * base[k]])
        w[2:] += rng.standard_normal(2) * sigma
        noise.push(t_ns, w)
    got = np.sqrt(noise.var_rad2_s2)
    np.testing.assert_allclose(got, sigma, rtol=0.2)
    # a NaN sample and a gap do not count: the variance stays where it was
    before = noise.var_rad2_s2
    noise.push(int(t[-1]) + 10_000_000, np.array([0.0, 0.0, math.nan, 20.0]))
    noise.push(int(t[-1]) + 20_000_000, np.array([0.0, 0.0, 500.0, 20.0]))
    noise.push(int(t[-1]) + 30_000_000, np.array([0.0, 0.0, 20.0, 20.0]))
    noise.push(int(t[-1]) + 900_000_000, np.array([0.0, 0.0, -400.0, 20.0]))
    noise.push(int(t[-1]) + 910_000_000, np.array([0.0, 0.0, 20.0, 20.0]))
    assert noise.var_rad2_s2 == before
    noise.reset()
    assert noise.var_rad2_s2 == (0.0, 0.0)
    assert NOISE_AVERAGING_SAMPLES == 100


# --- dead reckoning with the corrected twist of a simulated drive -------------------------------


class DeadReckoning:
    """A consumer of a twist stream: integrates (vx, yaw rate) held over each interval."""

    def __init__(self) -> None:
        self.distance_m = 0.0
        self.heading_rad = 0.0
        self.xy_m = np.zeros(2)
        self._last: tuple[int, float, float] | None = None

    def on_twist(self, t_ns: int, vx_m_s: float, yaw_rate_rad_s: float) -> None:
        if self._last is not None:
            t0, v, yr = self._last
            dt = (t_ns - t0) * 1e-9
            psi = self.heading_rad
            self.xy_m += dt * v * np.array([math.cos(psi), math.sin(psi)])
            self.distance_m += dt * v
            self.heading_rad += dt * yr
        self._last = (t_ns, vx_m_s, yaw_rate_rad_s)


def test_dead_reckoning_with_the_corrected_twist_beats_the_nominal_radius() -> None:
    """Tyres off nominal by millimetres (radius_offset_std_mm=3: rear -1.21 and +4.17 mm):
    dead reckoning with the raw wheel speeds and the nominal radius drifts by the expected
    ``mean(d) / r`` of the distance and ``(d_rr - d_rl) / (r l_T)`` rad per metre of heading;
    with the corrected twist (learned radii) the drift is a small fraction of that, and the
    twist's covariance matches its errors against the truth."""
    res = simulate("lane_change", seed=10, minutes=1.0, radius_offset_std_mm=3.0)
    veh = res.vehicle
    r, lt = veh.nominal_tire_radius_m, veh.track_width_m
    truth = res.truth
    d_rl, d_rr = (truth.wheel_radius_m[0, 2:] - r).tolist()
    assert (d_rl, d_rr) == pytest.approx((-1.21e-3, 4.17e-3), abs=1e-5)
    pipeline = EstimationPipeline(PipelineConfig(radius=RadiusEstimatorConfig()), veh)
    start_ns = int(truth.t_ns[0]) + 20_000_000_000  # the radii learned over the first 20 s
    corrected, raw = DeadReckoning(), DeadReckoning()
    stamps, errors, covs = [], [], []
    n_radii = n_odom = 0
    for sample in sim_samples(res, tire_forces=False):
        for out in pipeline.push(sample):
            n_radii += type(out) is RadiiOutput
            if type(out) is not WheelOdometryOutput:
                continue
            n_odom += 1
            tw = out.twist
            assert out.t_ns == tw.t_ns
            if out.t_ns < start_ns:
                continue
            corrected.on_twist(out.t_ns, tw.vx_m_s, tw.yaw_rate_rad_s)
            # the same wheel speeds with the nominal radius
            rl, rr = out.radii.of("wheel_rl")[0], out.radii.of("wheel_rr")[0]
            w_rl = (tw.vx_m_s - 0.5 * lt * tw.yaw_rate_rad_s) / rl
            w_rr = (tw.vx_m_s + 0.5 * lt * tw.yaw_rate_rad_s) / rr
            raw.on_twist(out.t_ns, 0.5 * r * (w_rl + w_rr), r * (w_rr - w_rl) / lt)
            k = min(int(np.searchsorted(truth.t_ns, out.t_ns)), truth.t_ns.size - 1)
            errors.append(
                [tw.vx_m_s - truth.velocity_m_s[k, 0], tw.yaw_rate_rad_s - truth.yaw_rate_rad_s[k]]
            )
            stamps.append(out.t_ns)
            covs.append(tw.covariance)
    assert n_odom == n_radii > 500  # one with every radii output, at the radii period
    # the truth over the same span
    k0, k1 = (int(np.searchsorted(truth.t_ns, t)) for t in (stamps[0], stamps[-1]))
    dt = np.diff(truth.t_ns[k0 : k1 + 1]) * 1e-9
    distance = float(np.sum(dt * truth.velocity_m_s[k0:k1, 0]))
    turned = float(np.sum(dt * truth.yaw_rate_rad_s[k0:k1]))
    assert 550.0 < distance < 750.0

    # raw: too short by mean(d) / r of the distance, turning right by (d_rr - d_rl) / (r l_T)
    expected_distance_error = -0.5 * (d_rl + d_rr) / r * distance  # -3.1 m
    expected_heading_error = -(d_rr - d_rl) / (r * lt) * distance  # -7.4 rad
    raw_distance_error = raw.distance_m - distance
    raw_heading_error = raw.heading_rad - turned
    assert raw_distance_error == pytest.approx(expected_distance_error, rel=0.1)
    assert raw_heading_error == pytest.approx(expected_heading_error, rel=0.1)
    # corrected: a small fraction of that (measured: 0.10 m and 0.09 rad)
    corrected_distance_error = corrected.distance_m - distance
    corrected_heading_error = corrected.heading_rad - turned
    assert abs(corrected_distance_error) < 0.1 * abs(expected_distance_error)
    assert abs(corrected_heading_error) < 0.05 * abs(expected_heading_error)
    # and the position (the raw heading drift makes a loop of it)
    true_xy = truth.position_enu_m[k1, :2] - truth.position_enu_m[k0, :2]
    c, s = math.cos(truth.yaw_rad[k0]), math.sin(truth.yaw_rad[k0])
    true_body = np.array([c * true_xy[0] + s * true_xy[1], -s * true_xy[0] + c * true_xy[1]])
    corrected_position_error = float(np.linalg.norm(corrected.xy_m - true_body))
    raw_position_error = float(np.linalg.norm(raw.xy_m - true_body))
    assert corrected_position_error < 0.1 * raw_position_error

    # the covariance is honest: normalized squared errors average about 1
    err = np.asarray(errors)
    cov = np.asarray(covs)
    z2 = err**2 / np.stack([cov[:, 0, 0], cov[:, 1, 1]], axis=1)
    assert 0.4 < float(np.mean(z2[:, 0])) < 1.5
    assert 0.6 < float(np.mean(z2[:, 1])) < 1.5
    assert 0.9 < float(np.mean(z2 < 4.0)) < 0.995
