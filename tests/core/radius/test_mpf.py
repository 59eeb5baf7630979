"""Motion model and MPF on a synthetic curvy drive generated here with NumPy."""

from __future__ import annotations

import numpy as np
import pytest

from tire_estimation.core.radius.model import RadiusMotionModel
from tire_estimation.core.radius.mpf import RadiusMPF

R_NOM, TRACK, WHEELBASE = 0.31, 1.55, 2.7
TRUE_REAR_ERR = (1.0e-3, -0.5e-3)


def make_drive(
    duration_s=300.0,
    dt_s=0.01,
    radius_error_m=(0.0, 0.0, *TRUE_REAR_ERR),
    gnss_rate_hz=1.0,
    gnss_std_m=1.5,
    seed=0,
    front_slip=None,
):
    """Curvy drive at 22-28 m/s (|ay| < 3 m/s^2): truth, wheel speeds (M, 4), GNSS fixes.

    ``front_slip(v, ax)`` optionally returns the front-wheel slip ratio (driven front axle).
    """
    rng = np.random.default_rng(seed)
    m = RadiusMotionModel(R_NOM, TRACK, WHEELBASE)
    n = round(duration_s / dt_s) + 1
    t = np.arange(n) * dt_s
    v = 25.0 + 3.0 * np.sin(2 * np.pi * t / 60.0)
    ax = 3.0 * 2 * np.pi / 60.0 * np.cos(2 * np.pi * t / 60.0)
    kappa = 0.003 * np.sin(2 * np.pi * t / 40.0) + 0.0015 * np.sin(2 * np.pi * t / 17.0 + 1.0)
    yr = v * kappa
    steer = np.arctan(WHEELBASE * kappa)
    yaw = np.concatenate([[0.3], 0.3 + np.cumsum(0.5 * (yr[1:] + yr[:-1]) * dt_s)])
    ym, vm = 0.5 * (yaw[1:] + yaw[:-1]), 0.5 * (v[1:] + v[:-1])
    east = np.concatenate([[0.0], np.cumsum(vm * np.cos(ym) * dt_s)])
    north = np.concatenate([[0.0], np.cumsum(vm * np.sin(ym) * dt_s)])
    radii = R_NOM + np.asarray(radius_error_m)
    ws = m.kinematic_wheel_speeds(v, yr, steer, radii)
    if front_slip is not None:
        ws[:, :2] *= (1.0 + front_slip(v, ax))[:, None]
    step = round(1.0 / gnss_rate_hz / dt_s)
    gi = np.arange(0, n, step)
    gnss = np.stack([east[gi], north[gi]], 1) + gnss_std_m * rng.standard_normal((gi.size, 2))
    return {
        "t": t,
        "t_ns": np.round(t * 1e9).astype(np.int64),
        "v": v,
        "ax": ax,
        "yr": yr,
        "steer": steer,
        "yaw": yaw,
        "east": east,
        "north": north,
        "ws": ws,
        "gi": gi,
        "gnss": gnss,
        "gnss_std": gnss_std_m,
    }


def test_virtual_speed_and_yaw_rate_from_known_trajectory():
    m = RadiusMotionModel(R_NOM, TRACK, WHEELBASE)
    v = np.array([5.0, 20.0, 30.0])
    yr = np.array([0.3, -0.05, 0.1])
    st = np.arctan(WHEELBASE * yr / v)
    err = np.array([0.0, 0.0, 1.0e-3, -0.5e-3])
    ws = m.kinematic_wheel_speeds(v, yr, st, R_NOM + err)
    # eq. (6): with the true radius errors the speed and yaw rate are recovered exactly
    v6, yr6 = m.speed_yaw_rate(ws, np.tile(err[2:], (3, 1)))
    np.testing.assert_allclose(v6, v, rtol=1e-12)
    np.testing.assert_allclose(yr6, yr, rtol=1e-12, atol=1e-14)
    # eq. (4): the virtual values are biased as in eq. (9): -(w3 d3 + w4 d4)/2 and ...
    vv, yv = m.virtual_speed_yaw_rate(ws)
    np.testing.assert_allclose(vv, v - 0.5 * (ws[:, 2] * 1e-3 + ws[:, 3] * -0.5e-3), rtol=1e-12)
    np.testing.assert_allclose(yv - yr, -(ws[:, 3] * -0.5e-3 - ws[:, 2] * 1e-3) / TRACK)
    # paper example (9): r = 0.27, l_T = 1.52, w3 = 76, w4 = 75.8, d3 = -1 mm
    pm = RadiusMotionModel(0.27, 1.52, 2.7)
    wsp = np.array([0.0, 0.0, 76.0, 75.8])
    v9, y9 = pm.virtual_speed_yaw_rate(wsp)
    assert float(v9) == pytest.approx(20.5, abs=0.01)
    assert float(y9) == pytest.approx(-0.036, abs=0.001)
    vt, yt = pm.speed_yaw_rate(wsp, np.array([-1e-3, 0.0]))
    assert float(vt - v9) == pytest.approx(-0.038, abs=1e-3)
    assert float(yt - y9) == pytest.approx(0.05, abs=1e-3)
    # steering yaw rate (eq. 31a) and front wheels rolling straight
    assert float(m.steering_yaw_rate(np.array(10.0), float(st[0]))) == pytest.approx(
        10.0 * yr[0] / v[0]
    )
    a, b = m.front_wheel_geometry(0.0)
    np.testing.assert_allclose(a, [1.0, 1.0])
    np.testing.assert_allclose(b, [-TRACK / 2, TRACK / 2])


def test_front_wheel_rolling_speed_matches_rigid_body_kinematics():
    m = RadiusMotionModel(R_NOM, TRACK, WHEELBASE)
    v, yr = 10.0, 0.4  # tight turn
    st = float(np.arctan(WHEELBASE * yr / v))
    a, b = m.front_wheel_geometry(st)
    # wheel centre speed magnitude = |yaw rate| x distance to the instantaneous centre
    rc = v / yr
    for i, y in enumerate((TRACK / 2, -TRACK / 2)):
        speed = abs(yr) * np.hypot(WHEELBASE, rc - y)
        assert a[i] * v + b[i] * yr == pytest.approx(speed, rel=1e-12)


def run_mpf(drive, n=500, seed=0, **kw):
    m = RadiusMotionModel(R_NOM, TRACK, WHEELBASE)
    rng = np.random.default_rng(seed)
    opts = {
        "prior_mean_std_m": 3e-3,
        "prior_noise_std_m": 1e-3,
        "prior_dof": 10.0,
        "forgetting_factor": 0.9998,
        "resample_threshold": 0.5,
        "position_noise_m_sqrt_s": 0.01,
        "yaw_noise_rad_sqrt_s": 0.002,
        "mean_random_walk_m_sqrt_s": 5e-5,
        "kernel_shrinkage": 0.98,
    }
    opts.update(kw)
    f = RadiusMPF(m, n, np.zeros(2), rng=rng, **opts)
    f.init_pose(
        np.array([drive["east"][0], drive["north"][0], drive["yaw"][0]]), np.diag([1, 1, 0.01])
    )
    fix_at = dict(zip(drive["gi"].tolist(), range(drive["gi"].size), strict=False))
    r = np.eye(2) * drive["gnss_std"] ** 2
    hist = []
    for k in range(1, drive["t"].size):
        f.predict(0.01, drive["ws"][k - 1])
        if k in fix_at:
            y = drive["gnss"][fix_at[k]]
            f.update(y, r, f.predict_fix(y, r, np.zeros(2)))
            if drive["t"][k] >= drive["t"][-1] - 60.0:
                hist.append(f.estimate().radius.mean)
    return f, np.mean(hist, axis=0)


@pytest.mark.parametrize(("rate_hz", "duration_s"), [(1.0, 300.0), (10.0, 200.0)])
def test_mpf_converges_on_synthetic_drive(rate_hz, duration_s):
    drive = make_drive(duration_s=duration_s, gnss_rate_hz=rate_hz, seed=1)
    f, last_minute = run_mpf(drive, seed=1)
    est = f.estimate()
    truth = np.array(TRUE_REAR_ERR)
    err = est.radius.mean - truth
    assert np.all(np.abs(last_minute - truth) < 0.5e-3), (last_minute, truth)
    assert np.all(np.abs(err) < 0.6e-3), err
    # the left-right difference is far better observed (eq. 9b)
    assert abs(np.diff(err)[0]) < 0.15e-3
    # pose tracks the truth
    assert np.hypot(est.pose[0] - drive["east"][-1], est.pose[1] - drive["north"][-1]) < 3.0
    assert np.all(np.isfinite(est.pose_cov)) and est.n_eff > 10
    assert est.resample_count > 5


def test_mpf_without_gnss_cannot_learn_and_stays_at_prior():
    drive = make_drive(duration_s=20.0, seed=2)
    drive["gi"] = np.array([], dtype=int)

    m = RadiusMotionModel(R_NOM, TRACK, WHEELBASE)
    f = RadiusMPF(
        m,
        200,
        np.zeros(2),
        3e-3,
        1e-3,
        10.0,
        0.9998,
        0.0,
        0.0,
        np.random.default_rng(2),
    )
    f.init_pose(np.zeros(3), np.eye(3) * 1e-6)
    for k in range(1, 2001):
        f.predict(0.01, drive["ws"][k - 1])
    est = f.estimate()
    assert np.all(np.abs(est.radius.mean) < 1e-3)  # prior mean 0, std 3 mm / sqrt(N)
    # the self-sampled NiW keeps the prior noise level (eq. 23-24 are self-consistent)
    np.testing.assert_allclose(np.sqrt(np.diag(est.radius.noise_cov)), 1e-3, rtol=0.3)


def test_paused_prediction_leaves_statistics_untouched():
    drive = make_drive(duration_s=2.0, seed=3)
    m = RadiusMotionModel(R_NOM, TRACK, WHEELBASE)
    f = RadiusMPF(
        m,
        100,
        np.zeros(2),
        3e-3,
        1e-3,
        10.0,
        0.999,
        0.0,
        0.0,
        np.random.default_rng(3),
    )
    f.init_pose(np.zeros(3), np.eye(3) * 1e-6)
    for k in range(10):
        f.predict(0.01, drive["ws"][k])
    mean, scale, dof = f.stats.mean.copy(), f.stats.scale.copy(), float(f.stats.dof)
    east = f.east.copy()
    f.predict(0.01, drive["ws"][10], learn=False)
    np.testing.assert_array_equal(f.stats.mean, mean)
    np.testing.assert_array_equal(f.stats.scale, scale)
    assert float(f.stats.dof) == dof
    assert np.all(f.east > east)


def _bare_mpf(n, lam, seed, prior_dof=10.0, gamma_std=(3e-3, 1e-3)):
    m = RadiusMotionModel(R_NOM, TRACK, WHEELBASE)
    return RadiusMPF(
        m, n, np.array([1e-3, -5e-4]), gamma_std[0], gamma_std[1], prior_dof, lam,
        0.0, 0.0, np.random.default_rng(seed),
    )  # fmt: skip


@pytest.mark.parametrize("k", [1, 7, 40])
def test_block_niw_update_equals_sequential_eq23_24(k):
    from tire_estimation.core import niw

    f = _bare_mpf(50, 0.99, seed=5)
    rng = np.random.default_rng(6)
    # a non-trivial starting point: correlated scale, spread means
    f._mu[...] += 1e-3 * rng.standard_normal((2, 50))
    f._lam[0, 1] = f._lam[1, 0] = 0.3 * f._lam[0, 0]
    ref = f.stats.copy()
    w = 1e-3 * rng.standard_normal((k, 2, 50))
    for j in range(k):
        niw.time_update(ref, 0.99)
        niw.measurement_update(ref, w[j].T)
    f._niw_block_update(w[:, 0].copy(), w[:, 1].copy())
    st = f.stats
    np.testing.assert_allclose(st.mean, ref.mean, rtol=1e-10, atol=1e-16)
    np.testing.assert_allclose(st.scale, ref.scale, rtol=1e-10, atol=1e-18)
    assert float(st.gamma) == pytest.approx(float(ref.gamma), rel=1e-12)
    assert float(st.dof) == pytest.approx(float(ref.dof), rel=1e-12)


def test_block_draws_have_the_niw_joint_law():
    """Without forgetting, a block is a draw of (mu, Sigma) from the NiW, then iid N(mu, Sigma)
    samples: Var(w_j) = (1 + gamma) E[Sigma], Cov(w_1, w_2) = gamma E[Sigma], and a block of one
    sample is the Student-t of eq. (27) (kurtosis 3 + 6 / (nu_t - 4))."""
    n = 400_000
    f = _bare_mpf(n, 1.0, seed=7, prior_dof=12.0, gamma_std=(1e-3, 1e-3))
    f._lam[0, 1] = f._lam[1, 0] = 0.5 * f._lam[0, 0]
    gamma, nu, d = float(f.stats.gamma), float(f.stats.dof), 2
    e_sigma = f.stats.scale[0] / (nu - d - 1.0)
    d3, d4 = f._draw_block(2)
    c = np.cov(np.stack([d3[0], d4[0], d3[1], d4[1]]))
    np.testing.assert_allclose(c[:2, :2], (1 + gamma) * e_sigma, rtol=0.03)
    np.testing.assert_allclose(c[2:, 2:], (1 + gamma) * e_sigma, rtol=0.03)
    np.testing.assert_allclose(c[:2, 2:], gamma * e_sigma, rtol=0.05)
    x = f._draw_block(1)[0][0] - 1e-3
    kurt = np.mean(x**4) / np.mean(x**2) ** 2
    nu_t = nu - d + 1.0
    assert kurt == pytest.approx(3.0 + 6.0 / (nu_t - 4.0), rel=0.1)
    assert np.mean(x) == pytest.approx(0.0, abs=5e-6)


def test_queued_predictions_equal_immediate_ones_when_paused():
    """learn=False propagation is deterministic: processing the queue in one block or sample by
    sample gives the same poses."""
    drive = make_drive(duration_s=3.0, seed=4)
    fa = _bare_mpf(20, 0.9998, seed=8)
    fb = _bare_mpf(20, 0.9998, seed=8)
    for f in (fa, fb):
        f.init_pose(np.array([0.0, 0.0, 0.3]), np.eye(3) * 1e-4)
    for k in range(150):
        steer = 0.05 if k % 3 == 0 else None
        fa.predict(0.01, drive["ws"][k], learn=False, steer_angle_rad=steer)
        fb.predict(0.01, drive["ws"][k], learn=False, steer_angle_rad=steer)
        fb.estimate()  # forces the queue to be processed after every sample
    np.testing.assert_allclose(fa.east, fb.east, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fa.north, fb.north, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fa.yaw, fb.yaw, rtol=0, atol=1e-12)
    assert np.all(fa.east > 0.5)


def _bias_mpf(n: int, bias_std: float, tau: float) -> RadiusMPF:
    model = RadiusMotionModel(R_NOM, TRACK, WHEELBASE)
    f = RadiusMPF(
        model, n, np.zeros(2), 1e-3, 1e-3, 10.0, 0.9998, 0.0, 0.0,
        np.random.default_rng(0), gnss_bias_std_m=bias_std, gnss_bias_time_constant_s=tau,
    )  # fmt: skip
    f.init_pose(np.zeros(3), np.diag([1e-14, 1e-14, 1e-14]))
    for a in (f._east, f._north, f._yaw):
        a[:] = 0.0  # exactly at the origin (init_pose regularizes its covariance)
    return f


def test_gnss_bias_is_the_kalman_filter_of_a_gauss_markov_error():
    """One particle at a known, standing pose: the marginalized GNSS bias is a scalar Kalman
    filter per axis and the weight update returns its predictive log-density."""
    sb, tau, dt = 1.0, 60.0, 0.1
    r = np.diag([1.5**2, 2.0**2])  # fix covariance = white part + sb^2 per axis
    f = _bias_mpf(1, sb, tau)
    rng = np.random.default_rng(3)
    b_ref, p_ref = np.zeros(2), np.full(2, sb**2)
    rw = np.diag(r) - sb**2
    phi = np.exp(-dt / tau)
    for _ in range(40):
        for _ in range(10):  # one second standing still between the fixes
            f.predict(dt, np.zeros(4), learn=False)
        y = rng.normal(0.0, 1.5, 2) + np.array([0.7, -0.4])
        pred = f.predict_fix(y, r, np.zeros(2))
        log_like = f.update(y, r, pred)
        # reference: b = phi^10 b, P = phi^20 P + sb^2 (1 - phi^20); S = P + R_w
        b_ref = phi**10 * b_ref
        p_ref = phi**20 * p_ref + sb**2 * (1 - phi**20)
        s = p_ref + rw
        ref_ll = float(np.sum(-0.5 * (np.log(2 * np.pi * s) + (y - b_ref) ** 2 / s)))
        assert log_like == pytest.approx(ref_ll, abs=1e-9)
        np.testing.assert_allclose(np.diag(pred.innovation_cov_m2), s, rtol=1e-9)
        k = p_ref / s
        b_ref = b_ref + k * (y - b_ref)
        p_ref = (1 - k) * p_ref
        np.testing.assert_allclose(f._bias[:, 0], b_ref, atol=1e-12)
        np.testing.assert_allclose(np.diag(f._bias_p), p_ref, rtol=1e-12)


def test_gnss_bias_off_uses_the_fix_covariance():
    f = _bias_mpf(50, 0.0, 120.0)
    r = np.eye(2) * 2.25
    pred = f.predict_fix(np.array([0.3, -0.2]), r, np.zeros(2))
    np.testing.assert_array_equal(pred.likelihood_cov_m2, r)
    np.testing.assert_array_equal(f._bias, 0.0)


def test_gnss_bias_fraction_takes_the_error_size_from_each_fix():
    """``gnss_bias_fraction`` f: sigma_b^2 = f lambda_min(R) for each fix. With a constant R
    the filter equals the one given that sigma_b directly; when the receiver reports a larger
    covariance the modelled error's level follows it."""
    model = RadiusMotionModel(R_NOM, TRACK, WHEELBASE)
    r = np.diag([2.5, 4.0])  # lambda_min 2.5: f = 0.4 gives sigma_b^2 = 1.0
    fixed = _bias_mpf(3, 1.0, 60.0)
    frac = RadiusMPF(
        model, 3, np.zeros(2), 1e-3, 1e-3, 10.0, 0.9998, 0.0, 0.0,
        np.random.default_rng(0), gnss_bias_time_constant_s=60.0, gnss_bias_fraction=0.4,
    )  # fmt: skip
    assert frac.bias_on and frac.bias_var == 0.0
    frac.observe_fix_cov(r)
    assert frac.bias_var == pytest.approx(1.0, rel=1e-12)
    frac.init_pose(np.zeros(3), np.diag([1e-14, 1e-14, 1e-14]))
    for a in (frac._east, frac._north, frac._yaw):
        a[:] = 0.0
    rng = np.random.default_rng(5)
    for _ in range(20):
        for f in (fixed, frac):
            for _ in range(10):
                f.predict(0.1, np.zeros(4), learn=False)
        y = rng.normal(0.0, 1.5, 2)
        frac.observe_fix_cov(r)
        ll = [f.update(y, r, f.predict_fix(y, r, np.zeros(2))) for f in (fixed, frac)]
        assert ll[1] == pytest.approx(ll[0], abs=1e-12)
        np.testing.assert_allclose(frac._bias, fixed._bias, atol=1e-12)
    # a fix with four times the covariance: the time update tends to 4 sigma_b^2
    frac.observe_fix_cov(4.0 * r)
    assert frac.bias_var == pytest.approx(4.0, rel=1e-12)
    for _ in range(2000):
        frac.predict(0.1, np.zeros(4), learn=False)
    pred = frac.predict_fix(np.zeros(2), 4.0 * r, np.zeros(2))
    np.testing.assert_allclose(pred.likelihood_cov_m2, 4.0 * r, rtol=1e-3)


def test_gnss_bias_std_overrides_the_fraction():
    model = RadiusMotionModel(R_NOM, TRACK, WHEELBASE)
    f = RadiusMPF(
        model, 3, np.zeros(2), 1e-3, 1e-3, 10.0, 0.9998, 0.0, 0.0,
        np.random.default_rng(0), gnss_bias_std_m=0.5, gnss_bias_fraction=0.8,
    )  # fmt: skip
    f.observe_fix_cov(np.eye(2) * 9.0)
    assert f.bias_var == pytest.approx(0.25)
    off = RadiusMPF(
        model, 3, np.zeros(2), 1e-3, 1e-3, 10.0, 0.9998, 0.0, 0.0,
        np.random.default_rng(0), gnss_bias_fraction=0.0,
    )  # fmt: skip
    off.observe_fix_cov(np.eye(2) * 9.0)
    assert not off.bias_on and off.bias_var == 0.0


def test_init_pose_counts_as_a_state_change_and_observing_a_covariance_does_not():
    """``version`` (the estimate cache key) moves with :meth:`RadiusMPF.init_pose`, not with
    :meth:`RadiusMPF.observe_fix_cov` (a model setting, no state change)."""
    f = _bias_mpf(5, 0.0, 120.0)
    v0 = f.version
    f.observe_fix_cov(np.eye(2) * 2.0)
    assert f.version == v0
    f.init_pose(np.zeros(3), np.eye(3) * 0.01)
    assert f.version == v0 + 1


def test_velocity_likelihood_is_the_gaussian_of_the_particle_mean_speed():
    """One particle: the Doppler velocity's log-likelihood is N(y; R(psi) [v - r l_y, r l_x],
    R + q n n' + p t t') with v of eq. (6a) at the NiW mean and p from E[Sigma] (eq. 32)."""
    from scipy.stats import multivariate_normal

    f = _bias_mpf(1, 0.0, 120.0)
    psi = 0.4
    f._yaw[:] = psi
    f._mu[:, 0] = [1.0e-3, -0.5e-3]
    w3, w4 = 80.0, 81.0
    lever = np.array([1.2, 0.3])
    yr, q = 0.05, 0.2**2
    r = np.array([[0.01, 0.002], [0.002, 0.02]])
    y = np.array([22.0, 10.5])
    upd = f.update_velocity(y, r, lever, yr, 0.2, (w3, w4), along_var_m2_s2=1e-3)
    v = 0.5 * (w3 * (R_NOM + 1.0e-3) + w4 * (R_NOM - 0.5e-3))
    vb = np.array([v - yr * lever[1], yr * lever[0]])
    c, s = np.cos(psi), np.sin(psi)
    h = np.array([[c, -s], [s, c]]) @ vb
    sigma = f._lam[:, :, 0] / (float(f._stats.dof) - 3.0)
    p = np.array([w3, w4]) @ sigma @ np.array([w3, w4]) / 4.0 + 1e-3
    t_vec, n_vec = np.array([c, s]), np.array([-s, c])
    cov = r + q * np.outer(n_vec, n_vec) + p * np.outer(t_vec, t_vec)
    assert upd.accepted
    assert upd.log_likelihood == pytest.approx(multivariate_normal(h, cov).logpdf(y), abs=1e-9)
    np.testing.assert_allclose(upd.innovation_m_s, y - h, atol=1e-12)
    np.testing.assert_allclose(upd.innovation_cov_m2_s2, cov, rtol=1e-12)


def test_velocity_heading_offset_rotates_each_particle_heading():
    """``heading_offset_rad`` (the heading at the velocity's time, -r tau): the likelihood is
    that of the particle heading psi + offset; same with the AUG-KF's innovation."""
    from scipy.stats import multivariate_normal

    f = _bias_mpf(1, 0.0, 120.0)
    f._yaw[:] = 0.4
    f._mu[:, 0] = 0.0
    w = 80.0
    r = np.eye(2) * 0.01
    v = w * R_NOM
    y = v * np.array([np.cos(0.35), np.sin(0.35)])  # the heading 0.05 rad earlier
    upd = f.update_velocity(y, r, np.zeros(2), 0.0, 0.2, (w, w), heading_offset_rad=-0.05)
    sigma = f._lam[:, :, 0] / (float(f._stats.dof) - 3.0)
    p = np.array([w, w]) @ sigma @ np.array([w, w]) / 4.0
    t_vec, n_vec = np.array([np.cos(0.35), np.sin(0.35)]), np.array([-np.sin(0.35), np.cos(0.35)])
    cov = r + 0.04 * np.outer(n_vec, n_vec) + p * np.outer(t_vec, t_vec)
    assert upd.log_likelihood == pytest.approx(multivariate_normal(y, cov).logpdf(y), abs=1e-9)
    np.testing.assert_allclose(upd.innovation_m_s, 0.0, atol=1e-12)
    # without the offset the 0.05 rad show as a cross-track innovation of v 0.05
    g = _bias_mpf(1, 0.0, 120.0)
    g._yaw[:] = 0.4
    g._mu[:, 0] = 0.0
    off = g.update_velocity(y, r, np.zeros(2), 0.0, 0.2, (w, w))
    cross = -np.sin(0.4) * off.innovation_m_s[0] + np.cos(0.4) * off.innovation_m_s[1]
    assert cross == pytest.approx(-v * np.sin(0.05), rel=1e-9)


def test_velocity_selects_the_particles_whose_radius_explains_the_speed():
    """Half the cloud has +2 mm on both rear radii, half 0; a velocity measured with +2 mm
    (0.5 m/s more at 80 rad/s) moves the weight to the first half; a gated-out velocity
    leaves the weights alone."""
    f = _bias_mpf(200, 0.0, 120.0)
    f._mu[:, :100] = 2e-3
    f._mu[:, 100:] = 0.0
    f._yaw[:] = 0.0
    w = 80.0
    v_true = w * (R_NOM + 2e-3)
    r = np.eye(2) * 0.05**2
    before = f.weights.copy()
    far = f.update_velocity(
        np.array([v_true + 30.0, 0.0]), r, np.zeros(2), 0.0, 0.2, (w, w), gate_nis=18.4
    )
    assert not far.accepted and far.nis > 18.4
    np.testing.assert_array_equal(f.weights, before)
    upd = f.update_velocity(np.array([v_true, 0.0]), r, np.zeros(2), 0.0, 0.2, (w, w))
    # innovation against the cloud mean (+1 mm): 80 rad/s x 1 mm
    assert upd.accepted and upd.innovation_m_s[0] == pytest.approx(0.08, abs=1e-9)
    # weight ratio of the two halves: exp(-0.5 (0.16^2 / S_0 - 0 / S_2)) / sqrt(S_2 / S_0)
    # with S = R_ee + p (heading east), p from each half's E[Sigma]
    k = 0.25 / (float(f._stats.dof) - 3.0)
    p = k * w * w * (f._lam[0, 0] + 2.0 * f._lam[0, 1] + f._lam[1, 1])
    s_a, s_b = r[0, 0] + p[150], r[0, 0] + p[0]
    ratio = np.exp(-0.5 * (v_true - w * R_NOM) ** 2 / s_a) * np.sqrt(s_b / s_a)
    assert f.resample_count == 0  # N_eff is 200 / 1.2: no resampling at threshold 0.5
    assert f.weights[150] / f.weights[0] == pytest.approx(ratio, rel=1e-9)
    assert f.weights[:100].sum() > 0.85
