"""Measurement-conditioned proposal of the stiffness MPF (core/stiffness/proposal.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats as sst
from scipy.special import logsumexp

from tire_estimation.core import niw
from tire_estimation.core.stiffness import mpf as stiffness_mpf
from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.core.stiffness.model import SingleTrackParams
from tire_estimation.core.stiffness.mpf import StiffnessMpf
from tire_estimation.core.stiffness.proposal import (
    marginal_log_likelihood,
    marginal_maha_logdet,
    measured_state_proposal,
)
from tire_estimation.core.stiffness.student_t import conditional_predictive, likelihood_params
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError


def test_gyro_proposal_one_step_equals_the_kalman_filter() -> None:
    # linear-Gaussian case: r_k = r_{k-1} + v, v ~ N(0, Q); y = r + b + e, b ~ N(b0, P),
    # e ~ N(0, R)
    # with the prior of r_{k-1} as N particles: the weighted draws are the Kalman posterior and
    # the mean weight is the Kalman predictive density of y
    rng = np.random.default_rng(11)
    n = 400_000
    m0, p0, q, r_var, b0, p_b, y = 0.1, 0.02**2, 0.01**2, 0.005**2, 0.003, 0.002**2, 0.13
    prior = m0 + np.sqrt(p0) * rng.standard_normal(n)
    out = measured_state_proposal(
        prior, y, np.full(n, b0), np.full(n, p_b), r_var, q, np.random.default_rng(12)
    )
    w = np.exp(out.log_weight - logsumexp(out.log_weight))
    # Kalman filter of the same model
    s_kf = p0 + q + p_b + r_var
    k_kf = (p0 + q) / s_kf
    mean_kf = m0 + k_kf * (y - m0 - b0)
    var_kf = (1.0 - k_kf) * (p0 + q)
    mean_pf = float(w @ out.state)
    var_pf = float(w @ (out.state - mean_pf) ** 2)
    assert abs(mean_pf - mean_kf) < 0.02 * np.sqrt(var_kf)
    assert abs(var_pf / var_kf - 1.0) < 0.02
    # log p(y) = log mean_i N(nu_i; 0, S) -> log N(y; m0 + b0, S_kf)
    log_py = float(logsumexp(out.log_weight) - np.log(n))
    assert abs(log_py - sst.norm(m0 + b0, np.sqrt(s_kf)).logpdf(y)) < 0.01
    # one particle: the draw has the Kalman moments of Q alone, the weight is N(nu; 0, S)
    one = measured_state_proposal(
        np.full(n, m0), y, np.full(n, b0), np.full(n, p_b), r_var, q, np.random.default_rng(13)
    )
    s1 = q + p_b + r_var
    assert abs(one.state.mean() - (m0 + q / s1 * (y - m0 - b0))) < 1e-4
    assert abs(one.state.var() / (q * (1.0 - q / s1)) - 1.0) < 0.01
    np.testing.assert_allclose(
        one.log_weight, sst.norm(0.0, np.sqrt(s1)).logpdf(y - m0 - b0), rtol=1e-12
    )
    np.testing.assert_allclose(one.nis, (y - m0 - b0) ** 2 / s1, rtol=1e-12)


def test_gyro_proposal_without_process_noise_keeps_the_yaw_rate() -> None:
    r = np.array([0.1, 0.2, 0.3])
    out = measured_state_proposal(
        r, 0.2, np.zeros(3), np.zeros(3), 1e-4, 0.0, np.random.default_rng(0)
    )
    np.testing.assert_array_equal(out.state, r)
    # the weights are the gyro likelihood itself: the particle at the gyro wins
    assert int(np.argmax(out.log_weight)) == 1


def test_marginal_rows_are_the_student_t_marginal() -> None:
    rng = np.random.default_rng(3)
    n = 5
    st = niw.init_stats(n, np.array([1.0, -2.0, 0.5]), 0.5, 9.0, np.diag([2.0, 1.0, 3.0]))
    st.mean += rng.standard_normal((n, 3))
    d = rng.standard_normal((n, 3, 3)) * 0.3
    d[:, 2, :] = 0.0  # gyro row: no stiffness term (eq. 12)
    lp = likelihood_params(st, d, np.diag([0.05, 0.04, 0.01]), np.zeros((n, 3, 3)))
    z = rng.standard_normal((n, 3))
    got2 = marginal_log_likelihood(z, lp.shape, lp.dof, (0, 1))
    got1 = marginal_log_likelihood(z, lp.shape, lp.dof, (0,))
    for i in range(n):
        nu = float(lp.dof)
        ref2 = sst.multivariate_t(loc=np.zeros(2), shape=lp.shape[i, :2, :2], df=nu).logpdf(
            z[i, :2]
        )
        ref1 = sst.t(df=nu, scale=np.sqrt(lp.shape[i, 0, 0])).logpdf(z[i, 0])
        assert np.isclose(got2[i], ref2, rtol=1e-10)
        assert np.isclose(got1[i], ref1, rtol=1e-10)
    # block-diagonal shape: the 3-D maha is the rows' maha plus the gyro term
    maha2, _ = marginal_maha_logdet(z, lp.shape, (0, 1))
    maha3 = np.einsum("ni,nij,nj->n", z, lp.shape_inv, z)
    np.testing.assert_allclose(maha3, maha2 + z[:, 2] ** 2 / lp.shape[:, 2, 2], rtol=1e-10)
    with pytest.raises(ValueError):
        marginal_maha_logdet(z, lp.shape, (0, 1, 2))


def test_conditional_predictive_on_the_ax_ay_rows_only() -> None:
    # eq. (41) with the 2-D measurement [ax, ay]: computed directly with the 2 x 3 d
    rng = np.random.default_rng(4)
    st = niw.init_stats(1, np.array([0.5, -1.0, 2.0]), 0.7, 11.0, np.diag([2.0, 1.5, 3.0]))
    d = rng.standard_normal((1, 3, 3)) * 0.5
    d[:, 2, :] = 0.0
    lp = likelihood_params(st, d, np.diag([0.1, 0.2, 0.05]), np.zeros((1, 3, 3)))
    e = np.array([[0.3, -0.2, 0.7]])
    maha2, _ = marginal_maha_logdet(e - lp.loc, lp.shape, (0, 1))
    cp = conditional_predictive(st, d, e, lp, maha2, 2)
    nu = float(lp.dof)
    l11 = lp.w_shape[0]
    d2 = d[0, :2, :]
    l22 = lp.shape[0, :2, :2]
    gain = l11 @ d2.T @ np.linalg.inv(l22)
    z2 = e[0, :2] - lp.loc[0, :2]
    m = float(z2 @ np.linalg.solve(l22, z2))
    assert float(cp.dof) == nu + 2.0
    np.testing.assert_allclose(cp.loc[0], st.mean[0] + gain @ z2, rtol=1e-10)
    ref_shape = (nu + m) / (nu + 2.0) * (l11 - gain @ d2 @ l11)
    np.testing.assert_allclose(cp.shape[0], ref_shape, rtol=1e-9)


def _mpf(proposal: str, jitter: float, n: int = 64, jitter_vx: float = 0.015) -> StiffnessMpf:
    veh = VehicleParams()
    cfg = StiffnessEstimatorConfig(
        n_particles=n,
        state_proposal=proposal,
        state_jitter_vx_m_s_sqrt_s=jitter_vx,
        imu_bias_states=False,
    )
    mpf = StiffnessMpf(cfg, SingleTrackParams.from_vehicle(veh), np.random.default_rng(7))
    # a yaw-rate random walk of ``jitter`` rad/s/sqrt(s) (deviation iii)
    mpf.jitter[2] = jitter
    mpf.initialize(np.array([20.0, 0.0, 0.0]), np.array([0.1, 0.1, 0.01]))
    return mpf


def test_mpf_gyro_proposal_weights_and_draw(monkeypatch: pytest.MonkeyPatch) -> None:
    # one update: the yaw rate moves toward the gyro by K = Q / S, and the weight increment is
    # N(nu; 0, S) times the Student-t marginal of the ax / ay rows at the new yaw rate
    from tire_estimation.core.stiffness.model import linearize

    monkeypatch.setattr(stiffness_mpf, "RESAMPLE_THRESHOLD", 0.0)
    mpf = _mpf("measured", 0.05)
    dt, y, delta, u = 0.01, np.array([0.1, 0.5, 0.02]), 0.01, (20.0, 20.0)
    mpf.predict(dt, learn=False)
    r_pred = mpf.x[:, 2].copy()
    q = 0.05**2 * dt
    s = q + mpf.r_cov[2, 2]
    state = mpf.rng.bit_generator.state
    expected = measured_state_proposal(
        r_pred, y[2], mpf.b[:, 2], mpf.p_bias[:, 2, 2], mpf.r_cov[2, 2], q, mpf.rng
    )
    mpf.rng.bit_generator.state = state
    x_new = mpf.x.copy()
    x_new[:, 2] = expected.state
    lin = linearize(x_new, delta, u, mpf.params)
    lp = likelihood_params(mpf.stats, lin.d, mpf.measurement_cov(delta, u), mpf.p_bias)
    ll2 = marginal_log_likelihood(y[None, :] - lin.h - mpf.b - lp.loc, lp.shape, lp.dof, (0, 1))
    log_w = np.log(mpf.weights) + expected.log_weight + ll2
    mpf.update(y, delta, u, learn=False)
    assert np.allclose(expected.state - r_pred, q / s * (y[2] - r_pred), atol=4 * np.sqrt(q))
    np.testing.assert_allclose(mpf.x[:, 2], expected.state, rtol=1e-12)
    assert mpf.resample_count == 0
    np.testing.assert_allclose(mpf.weights, np.exp(log_w - logsumexp(log_w)), rtol=1e-9)
    assert np.isclose(mpf.log_evidence, logsumexp(log_w), rtol=1e-10)


def test_mpf_gyro_proposal_follows_a_gyro_the_model_does_not_explain() -> None:
    # the gyro reads a yaw rate the model's yaw acceleration does not produce (straight
    # driving, no steering, gyro 0.05 rad/s): with the prior proposal the particles stay near 0
    # and the gyro only weighs them; with the gyro proposal the estimate follows the gyro
    est = {}
    for proposal in ("prior", "measured"):
        mpf = _mpf(proposal, 0.05, 200)
        y = np.array([0.0, 0.0, 0.05])
        for _ in range(100):
            mpf.predict(0.01, learn=False)
            mpf.update(y, 0.0, (20.0, 20.0), learn=False)
        est[proposal] = float(mpf.estimate().state[2])
    assert abs(est["measured"] - 0.05) < 0.01
    assert abs(est["prior"] - 0.05) > abs(est["measured"] - 0.05)


def test_state_proposal_is_validated() -> None:
    with pytest.raises(ConfigError):
        StiffnessEstimatorConfig(state_proposal="optimal")
    assert StiffnessEstimatorConfig().state_proposal == "prior"


def test_mpf_measured_proposal_draws_vx_from_the_measured_speed(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # kinematic speed model: vX and r are drawn given the speed and the gyro, the weight is
    # N(nu_v; 0, S_v) N(nu_r; 0, S_r) St(ay row), and predict() then leaves vX and r without
    # jitter (their random walk is drawn in update)
    from tire_estimation.core.stiffness.model import kinematic_speed_row, linearize

    monkeypatch.setattr(stiffness_mpf, "RESAMPLE_THRESHOLD", 0.0)
    mpf = _mpf("measured", 0.05, jitter_vx=0.2)
    dt, y, delta, speed = 0.01, np.array([0.3, 0.5, 0.02]), 0.01, 20.05
    mpf.predict(dt, learn=False)
    x_pred = mpf.x.copy()
    state = mpf.rng.bit_generator.state
    c = mpf.config
    pr = measured_state_proposal(
        x_pred[:, 2], y[2], mpf.b[:, 2], mpf.p_bias[:, 2, 2], mpf.r_cov[2, 2], 0.05**2 * dt,
        mpf.rng,
    )  # fmt: skip
    pv = measured_state_proposal(
        x_pred[:, 0], speed, 0.0, 0.0, c.speed_noise_std_m_s**2, 0.2**2 * dt, mpf.rng
    )
    mpf.rng.bit_generator.state = state
    x_new = x_pred.copy()
    x_new[:, 0], x_new[:, 2] = pv.state, pr.state
    vx = x_new[:, 0]
    lin = kinematic_speed_row(
        linearize(x_new, delta, (vx, vx), mpf.params), x_new, y[0], mpf.params
    )
    r_cov = np.tile(mpf.r_cov, (mpf.n, 1, 1))
    r_cov[:, 0, 0] = c.speed_noise_std_m_s**2
    b = mpf.b.copy()
    b[:, 0] = 0.0
    lp = likelihood_params(mpf.stats, lin.d, r_cov, mpf.p_bias)
    e_bar = np.array([speed, y[1], y[2]])[None, :] - lin.h - b
    ll = marginal_log_likelihood(e_bar - lp.loc, lp.shape, lp.dof, (1,))
    log_w = np.log(mpf.weights) + pr.log_weight + pv.log_weight + ll
    mpf.update(y, delta, (speed, speed), learn=False, vx_m_s=speed)
    np.testing.assert_allclose(mpf.x[:, 0], pv.state, rtol=1e-12)
    np.testing.assert_allclose(mpf.x[:, 2], pr.state, rtol=1e-12)
    np.testing.assert_allclose(mpf.weights, np.exp(log_w - logsumexp(log_w)), rtol=1e-9)
    # the draw moved vX toward the speed by K = Q / S
    k = 0.2**2 * dt / (0.2**2 * dt + c.speed_noise_std_m_s**2)
    assert np.allclose(pv.state - x_pred[:, 0], k * (speed - x_pred[:, 0]), atol=4 * 0.2 * 0.1)
    # next predict: vY keeps its jitter, vX and r follow eq. (9) only
    x1, rate = mpf.x.copy(), mpf.rate.copy()
    mpf.predict(dt, learn=False)
    np.testing.assert_allclose(mpf.x[:, [0, 2]], (x1 + dt * rate)[:, [0, 2]], rtol=1e-12)
    assert not np.allclose(mpf.x[:, 1], (x1 + dt * rate)[:, 1], rtol=1e-12, atol=0.0)
