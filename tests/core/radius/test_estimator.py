"""RadiusEstimator front-end: convergence, gates, bad input, config, persistence."""

from __future__ import annotations

import numpy as np
import pytest

from tests.core.radius.test_mpf import R_NOM, TRACK, TRUE_REAR_ERR, WHEELBASE, make_drive
from tire_estimation.core.geodesy import LocalTangentPlane
from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.radius.estimator import RadiusEstimator
from tire_estimation.core.radius.gnss import GNSS_MAX_REJECTIONS
from tire_estimation.core.radius.model import RadiusMotionModel
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError

VEH = VehicleParams(
    name="synthetic",
    nominal_tire_radius_m=R_NOM,
    track_width_m=TRACK,
    wheelbase_m=WHEELBASE,
    cg_to_front_axle_m=1.1,
    cg_to_rear_axle_m=1.6,
)
LTP = LocalTangentPlane(58.4, 15.6, 80.0)


def feed(est, drive, k0=0, k1=None, use_lla=False, every=None, hook=None):
    k1 = drive["t"].size if k1 is None else k1
    fix_at = dict(zip(drive["gi"].tolist(), range(drive["gi"].size), strict=False))
    r = np.eye(2) * drive["gnss_std"] ** 2
    cov3 = np.diag([drive["gnss_std"] ** 2] * 2 + [9.0])
    out = []
    for k in range(k0, k1):
        t = int(drive["t_ns"][k])
        est.on_steering(t, float(drive["steer"][k]))
        est.on_wheel_speeds(t, drive["ws"][k])
        if k in fix_at:
            y = drive["gnss"][fix_at[k]]
            if use_lla:
                lat, lon, alt = LTP.to_lla(y[0], y[1], 0.0)
                u = est.on_gnss_fix(t, float(lat), float(lon), float(alt), cov3)
            else:
                u = est.on_gnss_enu(t, y, r)
            out.append(u)
        if hook is not None:
            hook(k, t)
    return out


@pytest.fixture(scope="module")
def converged():
    drive = make_drive(duration_s=300.0, gnss_rate_hz=1.0, seed=5)
    # this drive's GNSS error is white: the model that says so (no Gauss-Markov part)
    est = RadiusEstimator(
        RadiusEstimatorConfig(run_aug_kf=True, gnss_bias_fraction=0.0),
        VEH,
        np.random.default_rng(5),
    )
    hist = []
    fixes = feed(
        est,
        drive,
        use_lla=True,
        hook=lambda k, t: (
            hist.append(est.estimate().radius_error_m) if k % 100 == 0 and k > 24000 else None
        ),
    )
    return drive, est, fixes, np.mean(hist, axis=0)


def test_estimator_converges_with_lla_input_and_baseline(converged):
    drive, est, fixes, last_minute = converged
    e = est.estimate()
    truth = np.array(TRUE_REAR_ERR)
    assert e.state == "running" and e.wheels == ("wheel_rl", "wheel_rr")
    assert np.all(np.abs(last_minute - truth) < 0.5e-3), last_minute
    assert np.all(np.abs(e.radius_error_m - truth) < 0.6e-3), e.radius_error_m
    assert np.all(e.radius_error_std_m > 0) and np.all(e.radius_error_std_m < 1e-3)
    assert np.all(e.radius_noise_std_m > 0)
    assert e.baseline is not None
    assert np.all(np.abs(e.baseline.radius_error_m - truth) < 0.5e-3), e.baseline.radius_error_m
    assert sum(f.accepted for f in fixes) >= len(fixes) - 3
    assert fixes[1].reason == "pose initialized"
    nis = np.array([f.nis for f in fixes[5:] if f.accepted])
    assert 0.8 < nis.mean() < 4.0
    assert e.speed_m_s == pytest.approx(drive["v"][-1], abs=0.05)
    assert abs(e.yaw_rate_rad_s - drive["yr"][-1]) < 0.01
    assert est.stats == {}


def test_gnss_error_share_on_a_white_gnss_drive():
    """``gnss_bias_fraction`` 0.5 reads half of each fix's variance as a slow Gauss-Markov
    error. On a drive whose GNSS error is all white it under-predicts the innovation (NIS
    about twice its 2 dof), so about 1 % of the fixes fall outside the 0.9999 gate
    (2 chi2_2 > 18.4); the radii still converge."""
    drive = make_drive(duration_s=300.0, gnss_rate_hz=1.0, seed=5)
    est = RadiusEstimator(
        RadiusEstimatorConfig(run_aug_kf=True, gnss_bias_fraction=0.5),
        VEH,
        np.random.default_rng(5),
    )
    assert est.mpf.bias_on and est.kf is not None
    assert est.kf.nx == 7
    fixes = feed(est, drive, use_lla=False)
    e = est.estimate()
    truth = np.array(TRUE_REAR_ERR)
    assert np.all(np.abs(e.radius_error_m - truth) < 0.6e-3), e.radius_error_m
    assert e.baseline is not None
    assert np.all(np.abs(e.baseline.radius_error_m - truth) < 0.5e-3), e.baseline.radius_error_m
    nis = np.array([f.nis for f in fixes[5:] if f.accepted])
    assert 2.5 < nis.mean() < 4.5  # white noise read as half white: NIS above its 2 dof
    assert est.stats.get("gnss_fix:outlier", 0) <= 0.02 * len(fixes)


def test_state_dict_round_trip(converged):
    _, est, _, _ = converged
    sd = est.state_dict()
    import json

    sd2 = json.loads(json.dumps(sd))
    other = RadiusEstimator(RadiusEstimatorConfig(run_aug_kf=True), VEH, np.random.default_rng(9))
    other.load_state_dict(sd2)
    a, b = est.estimate(), other.estimate()
    np.testing.assert_allclose(
        b.radius_error_m, a.radius_error_m, atol=0.1 * max(a.radius_error_std_m)
    )
    np.testing.assert_allclose(b.radius_noise_std_m, a.radius_noise_std_m, rtol=1e-6)
    np.testing.assert_allclose(b.radius_error_std_m, a.radius_error_std_m, rtol=0.3)
    np.testing.assert_allclose(b.baseline.radius_error_m, a.baseline.radius_error_m)
    assert b.state == "initializing"
    wrong = RadiusEstimator(
        RadiusEstimatorConfig(), VehicleParams(name="truck"), np.random.default_rng(0)
    )
    with pytest.raises(Exception, match="vehicle"):
        wrong.load_state_dict(sd2)
    other.reset()
    assert np.all(np.abs(other.estimate().radius_error_m) < 1e-3)


def test_bad_arrays_take_the_checks_of_the_fast_path():
    """float64 arrays (the bag and node inputs) take a fast path; it must drop exactly what the
    general checks drop."""
    drive = make_drive(duration_s=40.0, gnss_rate_hz=1.0, seed=7)
    est = RadiusEstimator(RadiusEstimatorConfig(), VEH, np.random.default_rng(7))
    feed(est, drive, 0, 1000)
    t = int(drive["t_ns"][999])
    ws = np.asarray(drive["ws"][999], dtype=float)
    before = est.estimate().pose.copy()
    for k, bad in enumerate(
        ([1.0, 2.0, np.nan, np.nan], [1.0, 2.0, np.inf, 3.0], [-np.inf, 1.0, 2.0, 3.0],
         [1e308, 1e308, 1.0, 1.0], [2000.0, 1.0, 1.0, 1.0], [1.0, -1500.0, 1.0, 1.0])
    ):  # fmt: skip
        est.on_wheel_speeds(t + 1 + k, np.array(bad))
    est.on_wheel_speeds(t, ws.copy())  # duplicate
    est.on_wheel_speeds(t - 1, ws.copy())  # out of order
    est.on_wheel_speeds(np.int64(t + 100), ws.astype(np.float32))  # other types: general path
    est.on_imu(t + 1, np.array([0.0, np.nan, 0.0]), np.zeros(3))
    est.on_imu(t + 2, np.zeros(3), np.array([0.0, 0.0, np.inf]))
    est.on_imu(t + 3, np.zeros(4), np.zeros(3))
    est.on_steering(t + 1, 1.5)
    est.on_steering(t + 2, float("inf"))
    est.on_steering(t + 3, np.float64(0.1))  # numpy scalar: general path, accepted
    assert est.stats == {
        "wheel_speeds:nan": 3,
        "wheel_speeds:out_of_range": 3,
        "wheel_speeds:duplicate": 1,
        "wheel_speeds:out_of_order": 1,
        "imu:nan": 2,
        "imu:wrong_length": 1,
        "steering:out_of_range": 1,
        "steering:nan": 1,
    }
    # the accepted samples were used: the float32 sample advanced the wheel stream
    assert est._streams["wheel"].last_t_ns == t + 100
    assert est._streams["steering"].last_t_ns == t + 3
    assert np.all(np.isfinite(est.estimate().pose)) and np.all(np.isfinite(before))


def test_a_wheel_not_reported_is_bridged():
    """A NaN wheel (not reported): a front one takes its side's rear speed and is counted; a
    rear one is a lost signal (the pose on the live wheel, learning paused), not a dropped
    sample."""
    drive = make_drive(duration_s=40.0, gnss_rate_hz=1.0, seed=7)
    est = RadiusEstimator(RadiusEstimatorConfig(), VEH, np.random.default_rng(7))
    feed(est, drive, 0, 1000)
    t = int(drive["t_ns"][999])
    ws = np.asarray(drive["ws"][999], dtype=float)
    est.on_wheel_speeds(t + 1, np.array([np.nan, ws[1], ws[2], ws[3]]))
    assert est.stats == {"wheel_speeds:missing_fl": 1} and est.signal_lost_wheel is None
    assert est._streams["wheel"].last_t_ns == t + 1
    est.on_wheel_speeds(t + 2, np.array([ws[0], ws[1], ws[2], np.nan]))
    e = est.estimate()
    assert est.stats["wheel_speeds:signal_lost_rr"] == 1 and est.signal_lost_wheel == "wheel_rr"
    assert e.state_reason == "wheel_rr signal lost" and e.active == (False, False)
    assert np.all(np.isfinite(e.pose)) and np.all(np.isfinite(e.radius_error_m))


def test_reversing_and_a_wrong_wheel_speed_scale_are_named():
    """Negative wheel speeds pause learning as "reversing" (not "low speed"); wheel speeds a
    third of the truth fail every two-fix initialization with their distance ratio kept."""
    est = RadiusEstimator(RadiusEstimatorConfig(n_particles=100), VEH, np.random.default_rng(8))
    m_ws = lambda v: np.full(4, v / R_NOM)  # noqa: E731
    est.on_gnss_enu(0, np.zeros(2), np.eye(2))
    t = 0
    for k in range(300):  # 3 s at 20 m/s
        t = k * 10_000_000
        est.on_wheel_speeds(t, m_ws(20.0))
    est.on_gnss_enu(t, np.array([59.8, 0.0]), np.eye(2))
    for k in range(1, 20):
        est.on_wheel_speeds(t + k * 10_000_000, m_ws(-5.0))
    assert est.estimate().state_reason == "reversing"
    scaled = RadiusEstimator(RadiusEstimatorConfig(n_particles=100), VEH, np.random.default_rng(8))
    for k in range(1200):  # 12 s at 20 m/s reported as 6.2 m/s, a fix a second
        t = k * 10_000_000
        if k % 100 == 0:
            scaled.on_gnss_enu(t, np.array([0.2 * k, 0.0]), np.eye(2) * 0.01)
        scaled.on_wheel_speeds(t, m_ws(20.0 * 0.31))
    assert scaled.estimate().state == "initializing"
    assert len(scaled.init_distance_ratios) >= 2
    assert np.median(scaled.init_distance_ratios) == pytest.approx(0.31, abs=0.02)
    assert est.init_distance_ratios == []


def test_bad_inputs_are_dropped_counted_and_estimates_stay_finite():
    drive = make_drive(duration_s=80.0, gnss_rate_hz=1.0, seed=6)
    est = RadiusEstimator(RadiusEstimatorConfig(), VEH, np.random.default_rng(6))
    feed(est, drive, 0, 3000)
    t = int(drive["t_ns"][2999])
    ws = drive["ws"][2999]
    est.on_wheel_speeds(t + 1, [1, 2, np.nan, np.nan])  # no rear wheel reported
    est.on_wheel_speeds(t + 2, [np.inf, 1, 2, 3])
    est.on_wheel_speeds(t - 5_000_000, ws)  # out of order
    est.on_wheel_speeds(t, ws)  # duplicate
    est.on_wheel_speeds(t + 3, [1.0, 2.0, 3.0])  # wrong length
    est.on_wheel_speeds(t + 4, {"wheel_fl": 1.0, "wheel_fr": 1.0, "wheel_xx": 1.0, "wheel_rr": 1})
    est.on_wheel_speeds(t + 5, "garbage")
    est.on_steering(t + 6, float("nan"))
    est.on_imu(t + 7, [0, 0, 0], [0, 0])
    outliers_before = est.stats.get("gnss_fix:outlier", 0)
    u = est.on_gnss_fix(t + 8, float("nan"), 15.6, 80.0, None)
    assert not u.accepted
    u = est.on_gnss_enu(
        t + 9, np.array([drive["east"][2999] + 500.0, drive["north"][2999]]), np.eye(2) * 2.25
    )
    assert not u.accepted and u.reason == "outlier" and u.nis > 100
    s = est.stats
    assert s["wheel_speeds:nan"] == 2 and s["steering:nan"] == 1 and s["gnss_fix:nan"] == 1
    assert s["wheel_speeds:out_of_order"] == 1 and s["wheel_speeds:duplicate"] == 1
    assert s["wheel_speeds:wrong_length"] == 1 and s["imu:wrong_length"] == 1
    assert s["wheel_speeds:unknown_wheel"] == 1 and s["wheel_speeds:bad_value"] == 1
    assert s["gnss_fix:outlier"] == outliers_before + 1
    e = est.estimate()
    assert e.state == "running"
    for v in (e.radius_error_m, e.radius_error_std_m, e.pose, e.pose_cov):
        assert np.all(np.isfinite(v))
    # a 10-minute gap re-initializes the pose but keeps the learned radii
    before = e.radius_error_m.copy()
    shift = 600 * 10**9
    drive2 = dict(drive)
    drive2["t_ns"] = drive["t_ns"] + shift
    feed(est, drive2, 3001, 3002)
    assert est.stats["wheel_speeds:gap"] == 1
    e = est.estimate()
    assert e.state == "initializing"
    np.testing.assert_allclose(e.radius_error_m, before)
    feed(est, drive2, 3002, 8000)
    e = est.estimate()
    assert e.state == "running", e.state_reason
    assert np.hypot(e.pose[0] - drive["east"][7999], e.pose[1] - drive["north"][7999]) < 5.0
    assert all(np.all(np.isfinite(x)) for x in (e.radius_error_m, e.pose, e.pose_cov))


def test_gnss_relocation_recovers_after_repeated_rejections():
    drive = make_drive(duration_s=90.0, gnss_rate_hz=1.0, seed=7)
    cfg = RadiusEstimatorConfig(n_particles=200)
    est = RadiusEstimator(cfg, VEH, np.random.default_rng(7))
    feed(est, drive, 0, 4000)
    drive2 = dict(drive)
    drive2["gnss"] = drive["gnss"] + np.array([800.0, -300.0])  # genuine relocation
    ups = feed(est, drive2, 4000, 9001)
    # GNSS_MAX_REJECTIONS consecutive outliers re-initialize the pose
    assert [u.accepted for u in ups[:GNSS_MAX_REJECTIONS]] == [False] * GNSS_MAX_REJECTIONS
    assert est.stats["gnss_fix:outlier"] == GNSS_MAX_REJECTIONS
    e = est.estimate()
    assert e.state == "running", e.state_reason
    assert (
        np.hypot(e.pose[0] - drive["east"][9000] - 800.0, e.pose[1] - drive["north"][9000] + 300.0)
        < 5.0
    )


def test_gates_pause_below_min_speed_and_when_braking():
    est = RadiusEstimator(RadiusEstimatorConfig(n_particles=100), VEH, np.random.default_rng(8))
    m_ws = lambda v: np.full(4, v / R_NOM)  # noqa: E731
    t = 0
    est.on_gnss_enu(0, np.zeros(2), np.eye(2))
    for k in range(300):  # 3 s straight at 20 m/s
        t = k * 10_000_000
        est.on_wheel_speeds(t, m_ws(20.0))
    est.on_gnss_enu(t, np.array([59.8, 0.0]), np.eye(2))
    est.on_wheel_speeds(t + 10_000_000, m_ws(20.0))
    assert est.estimate().state == "running"
    for k in range(1, 100):  # braking at 4 m/s^2
        est.on_wheel_speeds(t + (k + 1) * 10_000_000, m_ws(20.0 - 0.04 * k))
    e = est.estimate()
    assert e.state == "paused" and e.state_reason == "braking" and e.active == (False, False)
    est.on_imu(t + 101 * 10_000_000, [0, 0, 0], [0.0, 0.0, 9.81])
    est.on_wheel_speeds(t + 102 * 10_000_000, m_ws(0.5))
    assert est.estimate().state_reason == "low speed"
    # the floor is min_speed_m_s (1 m/s): at 2 m/s the radii are learned
    est.on_wheel_speeds(t + 103 * 10_000_000, m_ws(2.0))
    est.on_wheel_speeds(t + 104 * 10_000_000, m_ws(2.0))
    e = est.estimate()
    assert e.state == "running" and e.active == (True, True), e.state_reason


def test_learning_pauses_while_no_fix_is_accepted():
    """Without fixes nothing weighs the drawn radius errors: learning pauses after five fix
    periods (at least 1 s), the NiW statistics stay as they were, and the next fix resumes."""
    est = RadiusEstimator(RadiusEstimatorConfig(n_particles=100), VEH, np.random.default_rng(9))
    m_ws = lambda v: np.full(4, v / R_NOM)  # noqa: E731
    t = 0
    for k in range(601):  # 6 s straight at 20 m/s, fixes at 10 Hz
        t = k * 10_000_000
        if k % 10 == 0:
            est.on_gnss_enu(t, np.array([0.2 * k, 0.0]), np.eye(2))
        est.on_wheel_speeds(t, m_ws(20.0))
    assert est.estimate().state == "running"
    assert est.fix_overdue(t + 990_000_000) is False  # within max(1 s, 5 x 0.1 s)
    for k in range(601, 721):  # 1.2 s without a fix: paused from 1 s
        est.on_wheel_speeds(k * 10_000_000, m_ws(20.0))
    assert est.estimate().state_reason == "no GNSS fix"
    gamma_before = float(est.mpf.stats.gamma)
    for k in range(721, 801):
        est.on_wheel_speeds(k * 10_000_000, m_ws(20.0))
    e = est.estimate()
    assert e.state == "paused" and e.state_reason == "no GNSS fix", e.state_reason
    assert e.active == (False, False)
    assert float(est.mpf.stats.gamma) == gamma_before
    t = 801 * 10_000_000
    est.on_gnss_enu(t, np.array([0.2 * 801, 0.0]), np.eye(2))
    est.on_wheel_speeds(t + 10_000_000, m_ws(20.0))
    assert est.estimate().state == "running"
    # a 1 Hz receiver: the same 2 s without a fix is not yet overdue (5 periods)
    slow = RadiusEstimator(RadiusEstimatorConfig(n_particles=100), VEH, np.random.default_rng(9))
    for k in range(4):
        slow.on_gnss_enu(k * 1_000_000_000, np.array([20.0 * k, 0.0]), np.eye(2))
    assert slow.fix_overdue(5_000_000_000) is False
    assert slow.fix_overdue(8_500_000_000) is True


def test_heading_from_wheel_speeds_while_learning_below_steering_heading_speed():
    """Below ``STEERING_HEADING_SPEED_M_S`` the steer angle (eq. 31a) moves the heading only
    while the radii are paused; while they are learned, equal rear wheel speeds mean straight
    ahead whatever the steer angle says."""
    m_ws = lambda v: np.full(4, v / R_NOM)  # noqa: E731

    def yaw_change(min_speed_m_s: float) -> float:
        cfg = RadiusEstimatorConfig(n_particles=100, min_speed_m_s=min_speed_m_s)
        est = RadiusEstimator(cfg, VEH, np.random.default_rng(3))
        est.on_imu(0, [0.0, 0.0, 0.0], [0.0, 0.0, 9.81])
        est.on_gnss_enu(0, np.zeros(2), np.eye(2) * 1e-4)
        for k in range(1, 301):  # 3 s straight at 5 m/s, wheels straight ahead
            t = k * 10_000_000
            est.on_imu(t, [0.0, 0.0, 0.0], [0.0, 0.0, 9.81])
            est.on_wheel_speeds(t, m_ws(5.0))
        est.on_gnss_enu(t, np.array([15.0, 0.0]), np.eye(2) * 1e-4)
        yaw0 = est.estimate().pose[2]
        for k in range(301, 501):  # 2 s more with a steer angle of 0.2 rad reported
            t = k * 10_000_000
            est.on_steering(t, 0.2)
            est.on_imu(t, [0.0, 0.0, 0.0], [0.0, 0.0, 9.81])
            est.on_wheel_speeds(t, m_ws(5.0))
        return float(est.estimate().pose[2] - yaw0)

    # learning at 5 m/s: the wheel-speed difference (none) sets the heading
    assert abs(yaw_change(1.0)) < 0.01
    # paused (5 m/s below a 7 m/s floor): the steer angle turns the heading, about
    # v tan(0.2) / wheelbase = 0.37 rad/s for 2 s
    assert yaw_change(7.0) > 0.5


def test_config_validation_names_the_field():
    for kwargs, name in [
        ({"n_particles": 0}, "n_particles"),
        ({"forgetting_factor": 1.5}, "forgetting_factor"),
        ({"gnss_bias_fraction": 0.95}, "gnss_bias_fraction"),
        ({"gnss_latency_s": 1.5}, "gnss_latency_s"),
        ({"gnss_default_std_m": -1.0}, "gnss_default_std_m"),
        ({"wheels": "front"}, "wheels"),
        ({"min_speed_m_s": float("nan")}, "min_speed_m_s"),
        ({"run_aug_kf": "yes"}, "run_aug_kf"),
        ({"gnss_antenna_offset_x_m": 6.0}, "gnss_antenna_offset_x_m"),
        ({"gnss_antenna_offset_y_m": float("nan")}, "gnss_antenna_offset_y_m"),
        ({"radius_speed_coefficient_m_per_m2_s2": 1e-3}, "radius_speed_coefficient_m_per_m2_s2"),
    ]:
        with pytest.raises(ConfigError) as info:
            RadiusEstimatorConfig(**kwargs)
        assert info.value.field == name and name in str(info.value)
    with pytest.raises(ConfigError, match="bogus"):
        RadiusEstimatorConfig.from_dict({"bogus": 1})
    cfg = RadiusEstimatorConfig.from_dict({"n_particles": 100, "max_gap_s": 3})
    assert cfg.n_particles == 100 and cfg.max_gap_s == 3.0
    assert RadiusEstimatorConfig.from_dict(cfg.to_dict()) == cfg


def _front_drive_slip(with_resistance):
    """Driven front axle: slip = (m a_x + F_resist(v)) / C_x."""

    def slip(v, ax):
        f = VEH.mass_kg * ax
        if with_resistance:
            f = f + 0.5 * 1.2 * 0.7 * v**2 + 0.012 * VEH.mass_kg * 9.81
        return f / VEH.longitudinal_stiffness_front_n

    return slip


@pytest.mark.parametrize("with_resistance", [False, True])
def test_four_wheels_front_radii_and_the_driven_axle_limit(with_resistance):
    err = (0.8e-3, -0.4e-3, *TRUE_REAR_ERR)
    drive = make_drive(
        duration_s=240.0,
        gnss_rate_hz=10.0,
        seed=8,
        radius_error_m=err,
        front_slip=_front_drive_slip(with_resistance),
    )
    est = RadiusEstimator(
        RadiusEstimatorConfig(wheels="all", n_particles=300), VEH, np.random.default_rng(8)
    )
    feed(est, drive)
    e = est.estimate()
    assert e.wheels == ("wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr")
    front_err = e.radius_error_m[:2] - np.array(err[:2])
    if not with_resistance:
        assert np.all(np.abs(front_err) < 0.5e-3), front_err
    else:
        # the unmodelled constant drive slip is indistinguishable from a radius change: a driven
        # wheel spins faster, so it looks smaller by r F_resist / C_x (about 0.9 mm here)
        f_res = 0.5 * 1.2 * 0.7 * 25.0**2 + 0.012 * VEH.mass_kg * 9.81
        bias = R_NOM * f_res / VEH.longitudinal_stiffness_front_n
        assert np.all(np.abs(front_err + bias) < 0.3e-3), (front_err, bias)
        assert np.all(front_err < -0.5e-3)


def test_pose_initialization_uses_the_calibrated_gnss_latency():
    """A fix stamped t describes the antenna at t - 0.3 s. With gnss_latency_s = 0.3 the pose is
    initialized by inverting the same measurement model as the update, so the first fixes after
    initialization fit (small NIS); the initialization must not put the pose v * 0.3 = 7.5 m
    behind."""
    drive = make_drive(duration_s=30.0, gnss_rate_hz=10.0, gnss_std_m=0.2, seed=6)
    lag = 30  # samples of 10 ms
    gi = drive["gi"][drive["gi"] >= lag]
    noise = 0.2 * np.random.default_rng(7).standard_normal((gi.size, 2))
    drive["gnss"] = np.stack([drive["east"][gi - lag], drive["north"][gi - lag]], 1) + noise
    drive["gi"] = gi
    cfg = RadiusEstimatorConfig(gnss_latency_s=0.3, n_particles=200)
    est = RadiusEstimator(cfg, VEH, np.random.default_rng(6))
    fixes = feed(est, drive)
    k_init = next(i for i, f in enumerate(fixes) if f.reason == "pose initialized")
    after = fixes[k_init + 1 : k_init + 11]
    nis = np.array([f.nis for f in after])
    assert all(f.accepted for f in after)
    assert np.median(nis) < 6.0, nis


def test_pose_initialization_ties_each_position_to_its_heading():
    """With a compensated latency the initialization inverts ``y = p + R(yaw) l`` with the
    lever ``l = (-v tau, 0)`` (7.5 m for 0.3 s at 25 m/s). Each particle's position follows its
    own heading, so the antenna positions ``p_i + R(yaw_i) l`` of the initial cloud scatter like
    the fix (covariance R), not by ``|l| yaw_std`` more across the track."""
    drive = make_drive(duration_s=30.0, gnss_rate_hz=10.0, gnss_std_m=0.2, seed=6)
    lag = 30  # samples of 10 ms
    gi = drive["gi"][drive["gi"] >= lag]
    noise = 0.2 * np.random.default_rng(7).standard_normal((gi.size, 2))
    drive["gnss"] = np.stack([drive["east"][gi - lag], drive["north"][gi - lag]], 1) + noise
    drive["gi"] = gi
    cfg = RadiusEstimatorConfig(gnss_latency_s=0.3, n_particles=2000)
    est = RadiusEstimator(cfg, VEH, np.random.default_rng(6))
    clouds = []

    def at_init(k, _t):
        if est._pose_ok and not clouds:
            lx = -0.3 * float(drive["v"][k])
            mpf = est.mpf
            h = np.stack([mpf.east + lx * np.cos(mpf.yaw), mpf.north + lx * np.sin(mpf.yaw)])
            clouds.append((np.cov(h), float(np.std(mpf.yaw))))

    feed(est, drive, hook=at_init)
    cov, yaw_std = clouds[0]
    r_trace = 2 * 0.2**2
    # independent heading and position (the former initialization) would add (7.5 yaw_std)^2
    assert 7.5**2 * yaw_std**2 > r_trace
    assert np.trace(cov) < 1.2 * r_trace, (cov, yaw_std)


def test_speed_dependent_radius_switch_estimates_the_standstill_radius():
    """Wheels rolling on r = r_n + delta + k v^2: with ``radius_speed_coefficient_m_per_m2_s2``
    = k the estimate is delta; without it the estimate absorbs k v^2 (2.9 mm at 25-28 m/s)."""
    k = 4e-6
    drive = make_drive(duration_s=90.0, gnss_rate_hz=10.0, gnss_std_m=0.5, seed=8)
    m = RadiusMotionModel(R_NOM, TRACK, WHEELBASE)
    radii = R_NOM + np.array([0.0, 0.0, *TRUE_REAR_ERR])[None, :] + k * drive["v"][:, None] ** 2
    drive["ws"] = m.kinematic_wheel_speeds(drive["v"], drive["yr"], drive["steer"], radii)
    tail = drive["t"] > 60.0
    errs = {}
    for coeff in (0.0, k):
        cfg = RadiusEstimatorConfig(n_particles=300, radius_speed_coefficient_m_per_m2_s2=coeff)
        est = RadiusEstimator(cfg, VEH, np.random.default_rng(8))
        hist: list[np.ndarray] = []

        def record(i, _t, est=est, hist=hist):
            if tail[i] and i % 50 == 0:
                hist.append(est.estimate().radius_error_m)

        feed(est, drive, hook=record)
        errs[coeff] = np.mean(hist, axis=0) - np.array(TRUE_REAR_ERR)
    kv2 = k * float(np.mean(drive["v"][tail] ** 2))
    assert np.all(np.abs(errs[k]) < 0.3e-3), errs
    # without the switch the estimate drifts towards delta + k v^2 (2.9 mm here; 1.5 mm of it
    # after 60-90 s with the 3 mm prior)
    assert np.all((errs[0.0] > 1.0e-3) & (errs[0.0] < kv2 + 0.3e-3)), (errs, kv2)


def test_gnss_antenna_offset_is_added_to_the_vehicle_lever_arm():
    veh = VehicleParams(
        name="synthetic", nominal_tire_radius_m=R_NOM, gnss_antenna_position_m=(0.5, 0.1, 1.2)
    )
    cfg = RadiusEstimatorConfig(gnss_antenna_offset_x_m=0.7, gnss_antenna_offset_y_m=-0.3)
    est = RadiusEstimator(cfg, veh, np.random.default_rng(0))
    np.testing.assert_allclose(est.lever_arm_m, [1.2, -0.2])
    assert np.allclose(
        RadiusEstimator(RadiusEstimatorConfig(), veh, np.random.default_rng(0)).lever_arm_m,
        [0.5, 0.1],
    )


def _feed_velocity(est, drive, std=0.05, latency_s=0.0, seed=0):
    """``feed`` plus a Doppler velocity of base_link (antenna at base_link) with every fix,
    describing the vehicle ``latency_s`` before its stamp."""
    rng = np.random.default_rng(seed)
    dt = float(drive["t"][1] - drive["t"][0])
    lag = round(latency_s / dt)
    r = np.eye(2) * std**2
    ups = []

    def hook(k, t):
        if k in fix_set:
            j = max(k - lag, 0)
            v = drive["v"][j] * np.array([np.cos(drive["yaw"][j]), np.sin(drive["yaw"][j])])
            ups.append(est.on_gnss_velocity(t, v + std * rng.standard_normal(2), r))

    fix_set = set(drive["gi"].tolist())
    feed(est, drive, hook=hook)
    return ups


def test_gnss_velocity_pins_the_radius_scale():
    """With the Doppler velocity (beyond the paper) both rear radii are within 0.15 mm after
    2 min on the synthetic drive; the AUG-KF takes the same measurement."""
    drive = make_drive(duration_s=120.0, gnss_rate_hz=1.0, seed=5)
    cfg = RadiusEstimatorConfig(run_aug_kf=True, gnss_velocity_enabled=True)
    est = RadiusEstimator(cfg, VEH, np.random.default_rng(5))
    ups = _feed_velocity(est, drive)
    e = est.estimate()
    truth = np.array(TRUE_REAR_ERR)
    assert est.velocity_updates >= 100
    assert sum(u.reason == "updated" for u in ups) == est.velocity_updates
    assert np.all(np.abs(e.radius_error_m - truth) < 0.15e-3), e.radius_error_m
    assert e.baseline is not None
    assert np.all(np.abs(e.baseline.radius_error_m - truth) < 0.15e-3), e.baseline.radius_error_m
    nis = np.array([u.nis for u in ups if u.accepted])
    # the drive has no lateral velocity, the model allows 0.2 m/s of it: NIS below its 2 dof
    assert 0.4 < nis.mean() < 1.5
    assert est.stats == {}


def test_gnss_velocity_disabled_changes_nothing():
    drive = make_drive(duration_s=40.0, gnss_rate_hz=1.0, seed=7)
    off = RadiusEstimatorConfig(gnss_velocity_enabled=False)
    a = RadiusEstimator(off, VEH, np.random.default_rng(7))
    b = RadiusEstimator(off, VEH, np.random.default_rng(7))
    feed(a, drive)
    ups = _feed_velocity(b, drive)
    assert {u.reason for u in ups} == {"disabled"} and b.velocity_updates == 0
    np.testing.assert_array_equal(a.estimate().radius_error_m, b.estimate().radius_error_m)
    np.testing.assert_array_equal(a.estimate().pose, b.estimate().pose)


def test_gnss_velocity_latency_is_compensated():
    """A Doppler velocity 0.3 s late: not compensated, its along-track innovation follows the
    acceleration with the slope -0.3 s (v(t - 0.3) ~ v(t) - 0.3 a, the residual signature of
    the latency); with ``gnss_velocity_latency_s`` 0.3 the slope is gone."""
    drive = make_drive(duration_s=120.0, gnss_rate_hz=1.0, seed=5)
    slopes = {}
    for name, lat in (("ignored", 0.0), ("compensated", 0.3)):
        cfg = RadiusEstimatorConfig(gnss_velocity_enabled=True, gnss_velocity_latency_s=lat)
        est = RadiusEstimator(cfg, VEH, np.random.default_rng(5))
        ups = _feed_velocity(est, drive, latency_s=0.3)
        k = np.array([int(g) for g in drive["gi"]])[-len(ups) :]
        ok = np.array([u.accepted for u in ups])
        yaw = drive["yaw"][k]
        along = np.array(
            [np.cos(a) * u.innovation_m_s[0] + np.sin(a) * u.innovation_m_s[1]
             for a, u in zip(yaw, ups, strict=True)]
        )  # fmt: skip
        ax = drive["ax"][k]
        slopes[name] = np.polyfit(ax[ok], along[ok], 1)[0]
    assert slopes["ignored"] == pytest.approx(-0.3, abs=0.06), slopes
    assert abs(slopes["compensated"]) < 0.06, slopes


def test_gnss_velocity_is_not_used_while_accelerating():
    """``gnss_velocity_max_accel_m_s2``: a velocity while the rear wheels accelerate by more
    than the gate is skipped (reason ``accelerating``, counted, no drop): an unknown latency
    ``tau`` biases the speed by ``tau a`` with the sign of ``a``. Drive: |ax| up to 0.31 m/s^2,
    velocity 0.3 s late and not compensated, gate 0.15 m/s^2."""
    drive = make_drive(duration_s=120.0, gnss_rate_hz=1.0, seed=5)
    fix_ax = {}
    for k in drive["gi"].tolist():
        fix_ax[int(drive["t_ns"][k])] = float(drive["ax"][max(k - 30, 0)])
    cfg = RadiusEstimatorConfig(gnss_velocity_enabled=True, gnss_velocity_max_accel_m_s2=0.15)
    est = RadiusEstimator(cfg, VEH, np.random.default_rng(5))
    ups = _feed_velocity(est, drive, latency_s=0.3)
    skipped = [u for u in ups if u.reason == "accelerating"]
    used = [u for u in ups if u.accepted]
    assert len(skipped) == est.velocity_skipped_accel and len(used) == est.velocity_updates
    # |cos| > 0.48 two thirds of the time
    assert 65 < len(skipped) < 100 and len(used) > 25, (len(skipped), len(used))
    # the gate reads the wheel acceleration at the velocity's time (0.2 s difference)
    assert max(abs(fix_ax[u.t_ns]) for u in used) < 0.18
    assert min(abs(fix_ax[u.t_ns]) for u in skipped) > 0.12
    assert "gnss_velocity:accelerating" not in est.stats  # not bad input: nothing dropped
    open_gate = RadiusEstimator(
        RadiusEstimatorConfig(gnss_velocity_enabled=True, gnss_velocity_max_accel_m_s2=100.0),
        VEH,
        np.random.default_rng(5),
    )
    assert sum(u.accepted for u in _feed_velocity(open_gate, drive, latency_s=0.3)) > len(used)
    assert open_gate.velocity_skipped_accel == 0


def test_bad_gnss_velocities_are_dropped_and_counted():
    drive = make_drive(duration_s=30.0, gnss_rate_hz=1.0, seed=6)
    est = RadiusEstimator(
        RadiusEstimatorConfig(gnss_velocity_enabled=True), VEH, np.random.default_rng(6)
    )
    feed(est, drive)
    t = int(drive["t_ns"][-1])
    v = np.array([25.0, 0.0, 0.0])
    bad = [
        (t + 1, [np.nan, 0.0, 0.0], None),
        (t + 2, [1.0], None),
        (t + 3, v, -np.eye(3)),
        (t + 4, [300.0, 0.0, 0.0], None),
        (t + 5, "garbage", None),
    ]
    for stamp, vel, cov in bad:
        assert not est.on_gnss_velocity(stamp, vel, cov).accepted
    far = est.on_gnss_velocity(t + 6, np.array([80.0, 0.0, 0.0]), np.eye(3) * 0.01)
    assert not far.accepted and far.reason == "outlier"
    assert not est.on_gnss_velocity(t + 2, v, None).accepted  # out of order
    s = est.stats
    assert s["gnss_velocity:nan"] == 1 and s["gnss_velocity:wrong_length"] == 1
    assert s["gnss_velocity:bad_covariance"] == 1 and s["gnss_velocity:out_of_range"] == 1
    assert s["gnss_velocity:bad_value"] == 1 and s["gnss_velocity:out_of_order"] == 1
    assert s["gnss_velocity:outlier"] == 1
    e = est.estimate()
    assert all(np.all(np.isfinite(x)) for x in (e.radius_error_m, e.pose, e.pose_cov))


def test_bad_gnss_covariances_are_dropped_and_a_fix_without_altitude_is_used():
    """A fix covariance that is NaN, infinite, negative or not positive semi-definite drops the
    fix (``gnss_fix:bad_covariance``); an all-zero one is "not reported" (the default std). A
    NaN altitude (none reported) keeps the fix, counted ``gnss_fix:no_altitude``, out of the
    road-grade fit."""
    drive = make_drive(duration_s=40.0, gnss_rate_hz=1.0, seed=8)
    est = RadiusEstimator(RadiusEstimatorConfig(), VEH, np.random.default_rng(8))
    feed(est, drive, 0, 3000, use_lla=True)
    assert est.estimate().state == "running"
    before = dict(est.stats)  # outliers while converging
    t = int(drive["t_ns"][2999])
    lat, lon, alt = (float(v) for v in LTP.to_lla(drive["east"][2999], drive["north"][2999], 0))
    good = [2.25, 0.0, 0.0, 0.0, 2.25, 0.0, 0.0, 0.0, 9.0]
    bad = (
        [np.nan, *good[1:]],
        [*good[:4], np.inf, *good[5:]],
        [*good[:8], -9.0],  # negative vertical variance
        [2.25, 0.0, 5.0, 0.0, 2.25, 0.0, 5.0, 0.0, 9.0],  # |correlation| > 1
        [2.25, 1.0, 0.0, 0.0, 2.25, 0.0, 0.0, 0.0, 9.0],  # not symmetric
    )
    for k, cov in enumerate(bad):
        u = est.on_gnss_fix(t + 1 + k, lat, lon, alt, np.reshape(cov, (3, 3)))
        assert not u.accepted and u.reason == "bad_covariance"
    assert est.stats == {**before, "gnss_fix:bad_covariance": len(bad)}
    fit = est.grade._fit.pts  # (distance, altitude) points of the road-grade fit
    last = fit[-1]
    assert last[0] < est.grade.distance_m
    u = est.on_gnss_fix(t + 10, lat, lon, float("nan"), np.reshape(good, (3, 3)))
    assert u.accepted and u.nis < 20.0
    assert est.stats["gnss_fix:no_altitude"] == 1
    assert fit[-1] == last
    u = est.on_gnss_fix(t + 11, lat, lon, alt, np.zeros((3, 3)))  # not reported: the default
    assert u.accepted
    assert fit[-1][0] == est.grade.distance_m
    assert est.stats == {**before, "gnss_fix:bad_covariance": len(bad), "gnss_fix:no_altitude": 1}
