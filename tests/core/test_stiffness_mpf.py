"""Algorithm 1 building blocks (Berntorp & Di Cairano 2018) and a short simulated run."""

from __future__ import annotations

import numpy as np
from scipy import stats as sst

from tire_estimation.core import niw
from tire_estimation.core.stiffness_config import StiffnessEstimatorConfig
from tire_estimation.core.stiffness_estimator import StiffnessEstimator
from tire_estimation.core.stiffness_mpf import (
    ConditionalPredictive,
    bias_update,
    conditional_predictive,
    likelihood_params,
    log_likelihood,
    sample_student_t,
)
from tire_estimation.sim import SensorConfig, simulate


def _spd(rng: np.random.Generator, n: int, scale: float = 1.0) -> np.ndarray:
    a = rng.standard_normal((n, 3, 3))
    return scale * (a @ np.swapaxes(a, 1, 2) + 0.5 * np.eye(3))


def test_bias_kf_vectorized_matches_loop() -> None:
    rng = np.random.default_rng(1)
    n = 3
    b = rng.standard_normal((n, 3))
    p = _spd(rng, n, 0.01)
    resid = rng.standard_normal((n, 3))
    extra = _spd(rng, n, 0.001)
    r = np.diag([0.01, 0.02, 0.001])
    b_ref, p_ref = b.copy(), p.copy()
    for i in range(n):
        s = p[i] + r + extra[i]
        k = p[i] @ np.linalg.inv(s)
        b_ref[i] = b[i] + k @ resid[i]
        p_ref[i] = p[i] - k @ s @ k.T
    bias_update(b, p, resid, extra, r)
    np.testing.assert_allclose(b, b_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(p, p_ref, rtol=1e-9, atol=1e-12)


def _stats(n: int) -> niw.NiwStats:
    rng = np.random.default_rng(2)
    st = niw.init_stats(n, np.array([1.0, -2.0, 0.5]), 0.5, 9.0, np.diag([2.0, 1.0, 3.0]))
    st.mean += rng.standard_normal((n, 3))
    return st


def test_student_t_likelihood_matches_scipy() -> None:
    rng = np.random.default_rng(3)
    n = 4
    st = _stats(n)
    d = rng.standard_normal((n, 3, 3)) * 0.3
    p_bias = _spd(rng, n, 0.01)
    r = np.diag([0.05, 0.05, 0.01])
    lp = likelihood_params(st, d, r, p_bias)
    e = rng.standard_normal((n, 3))
    got = log_likelihood(e, lp)
    nu = 9.0 - 3 + 1
    for i in range(n):
        shape = (1.5 / nu) * d[i] @ st.scale[i] @ d[i].T + (nu - 2) / nu * (r + p_bias[i])
        ref = sst.multivariate_t(loc=d[i] @ st.mean[i], shape=shape, df=nu).logpdf(e[i])
        assert np.isclose(got[i], ref, rtol=1e-10)


def test_conditional_predictive_moments() -> None:
    rng = np.random.default_rng(4)
    st = _stats(1)
    d = rng.standard_normal((1, 3, 3)) * 0.5
    r = np.diag([0.1, 0.1, 0.1])
    lp = likelihood_params(st, d, r, np.zeros((1, 3, 3)))
    e = np.array([[0.3, -0.2, 0.1]])
    cp = conditional_predictive(st, d, e, lp)
    nu = float(cp.dof)
    assert nu == 7.0 + 3.0
    # moments of the sampler
    m = 200_000
    big = ConditionalPredictive(
        loc=np.repeat(cp.loc, m, 0), shape=np.repeat(cp.shape, m, 0), dof=cp.dof
    )
    s = sample_student_t(big, np.random.default_rng(5))
    np.testing.assert_allclose(s.mean(0), cp.loc[0], atol=0.02)
    np.testing.assert_allclose(np.cov(s.T), cp.shape[0] * nu / (nu - 2), rtol=0.05, atol=0.01)
    # Gaussian limit: mean equals the Kalman conditional mean of the joint (w, d w + e)
    s11 = lp.w_shape[0]
    s22 = lp.shape[0]
    k = s11 @ d[0].T @ np.linalg.inv(s22)
    np.testing.assert_allclose(cp.loc[0], st.mean[0] + k @ (e[0] - d[0] @ st.mean[0]))


def _run(minutes: float, n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    # bias-free sensors as in the paper's simulation study (Sec. VI-A)
    sensors = SensorConfig(
        accel_bias_initial_std_m_s2=0.0,
        gyro_bias_initial_std_rad_s=0.0,
        accel_bias_random_walk_m_s2_sqrt_s=0.0,
        gyro_bias_random_walk_rad_s_sqrt_s=0.0,
    )
    sim = simulate("stiffness_step", seed=seed, minutes=minutes, sensors=sensors)
    cfg = StiffnessEstimatorConfig(
        n_particles=n,
        accel_bias_std_m_s2=0.0,
        gyro_bias_std_rad_s=0.0,
        accel_bias_walk_m_s2_sqrt_s=0.0,
        gyro_bias_walk_rad_s_sqrt_s=0.0,
        initial_stiffness_factor=0.7,
        rolling_resistance_n=177.0,
        drag_n_s2_m2=0.42,
    )
    est = StiffnessEstimator(cfg, sim.vehicle, np.random.default_rng(seed))
    ev = [
        (int(t), 0, v)
        for t, v in zip(sim.wheel_speeds.t_ns, sim.wheel_speeds.wheel_speed_rad_s, strict=False)
    ]
    ev += [(int(t), 1, v) for t, v in zip(sim.steering.t_ns, sim.steering.angle_rad, strict=False)]
    imu = sim.imu
    ev += [
        (int(t), 2, (g, a))
        for t, g, a in zip(
            imu.t_ns, imu.angular_velocity_rad_s, imu.linear_acceleration_m_s2, strict=False
        )
    ]
    ev.sort(key=lambda e: (e[0], e[1]))
    ts, cs, truth = [], [], []
    for t, kind, v in ev:
        if kind == 0:
            est.on_wheel_speeds(t, v)
        elif kind == 1:
            est.on_steering(t, float(v))
        else:
            est.on_imu(t, v[0], v[1])
            j = min(int(np.searchsorted(sim.truth.t_ns, t)), sim.truth.t_ns.size - 1)
            ts.append((t - int(imu.t_ns[0])) * 1e-9)
            cs.append(est.estimate().stiffness)
            truth.append(sim.truth.stiffness[j])
    return np.asarray(ts), np.asarray(cs), np.asarray(truth)


def test_mpf_learns_cornering_stiffness_and_tracks_drop() -> None:
    t, c, truth = _run(0.75, 100, 1)
    rel = c / truth - 1.0
    cyf = rel[:, 1]
    # starts 30 % low (initial guess 70 % of nominal)
    assert abs(cyf[0] + 0.3) < 0.1
    # after excitation, before the step at 30 s: within 15 %
    pre = (t > 10.0) & (t < 29.0)
    assert np.mean(np.abs(cyf[pre])) < 0.15
    # after the 50 % drop: adapts within 12 s
    post = t > 40.0
    assert np.mean(np.abs(cyf[post])) < 0.25
    assert np.mean(c[post, 1]) < 0.75 * np.mean(c[pre, 1])
