"""NiW statistics against closed-form / brute-force references."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats as sps

from tire_estimation.core import niw


def _batch_posterior(mean0, kappa0, nu0, lam0, x):
    """Standard batch NiW posterior (Murphy 2007) for data x (M, d)."""
    m = x.shape[0]
    xbar = x.mean(axis=0)
    s = (x - xbar).T @ (x - xbar)
    kappa = kappa0 + m
    mean = (kappa0 * mean0 + m * xbar) / kappa
    lam = lam0 + s + kappa0 * m / kappa * np.outer(xbar - mean0, xbar - mean0)
    return mean, 1.0 / kappa, nu0 + m, lam


@pytest.mark.parametrize("d", [1, 2, 3])
def test_recursive_update_equals_batch_posterior(d):
    rng = np.random.default_rng(1)
    mean0 = rng.normal(size=d)
    lam0 = np.eye(d) * 2.0
    st = niw.init_stats(4, mean0, 0.5, d + 3.0, lam0, shared=False)
    x = rng.normal(size=(25, 4, d))
    for k in range(25):
        niw.time_update(st, 1.0)  # lambda = 1: no forgetting
        niw.measurement_update(st, x[k])
    for i in range(4):
        mean, gamma, nu, lam = _batch_posterior(mean0, 2.0, d + 3.0, lam0, x[:, i])
        np.testing.assert_allclose(st.mean[i], mean, rtol=1e-12)
        np.testing.assert_allclose(st.gamma[i], gamma, rtol=1e-12)
        np.testing.assert_allclose(st.dof[i], nu, rtol=1e-12)
        np.testing.assert_allclose(st.scale[i], lam, rtol=1e-12)


def test_shared_and_per_particle_gamma_agree():
    rng = np.random.default_rng(2)
    a = niw.init_stats(3, np.zeros(2), 1.0, 6.0, np.eye(2), shared=True)
    b = niw.init_stats(3, np.zeros(2), 1.0, 6.0, np.eye(2), shared=False)
    for _ in range(10):
        w = rng.normal(size=(3, 2))
        for s in (a, b):
            niw.time_update(s, 0.95)
            niw.measurement_update(s, w)
    np.testing.assert_allclose(a.mean, b.mean)
    np.testing.assert_allclose(a.scale, b.scale)
    np.testing.assert_allclose(np.broadcast_to(a.dof, (3,)), b.dof)


def test_forgetting_tracks_a_changed_mean_and_limits_dof():
    rng = np.random.default_rng(3)
    lam = 0.98  # window h = 50 samples
    st = niw.init_stats(1, np.zeros(1), 1.0, 5.0, np.eye(1) * 3.0)
    no_forget = niw.init_stats(1, np.zeros(1), 1.0, 5.0, np.eye(1) * 3.0)
    for k in range(2000):
        x = (0.0 if k < 1000 else 5.0) + rng.normal(size=(1, 1))
        niw.time_update(st, lam)
        niw.measurement_update(st, x)
        niw.time_update(no_forget, 1.0)
        niw.measurement_update(no_forget, x)
    # steady state: nu -> 1 / (1 - lambda), gamma -> 1 - lambda
    assert float(st.dof) == pytest.approx(1.0 / (1.0 - lam), rel=1e-6)
    assert float(st.gamma) == pytest.approx(1.0 - lam, rel=1e-6)
    assert st.mean[0, 0] == pytest.approx(5.0, abs=0.4)
    assert no_forget.mean[0, 0] == pytest.approx(2.5, abs=0.2)  # averages both halves
    est = niw.mmse(st, np.ones(1))
    assert est.noise_cov[0, 0] == pytest.approx(1.0, rel=0.35)  # unit-variance data


def test_predictive_matches_closed_form_d1_and_monte_carlo():
    # d = 1: the NiW predictive is a Student-t with nu - d + 1 dof, scale^2 (1+g) L/(nu-d+1)
    st = niw.init_stats(1, np.array([0.3]), 0.25, 7.0, np.array([[4.0]]))
    nu_t = 7.0
    scale = np.sqrt(1.25 * 4.0 / nu_t)
    x = np.linspace(-3, 3, 7)[:, None]
    st1 = niw.init_stats(7, np.array([0.3]), 0.25, 7.0, np.array([[4.0]]))
    ref = sps.t.logpdf(x[:, 0], df=nu_t, loc=0.3, scale=scale)
    np.testing.assert_allclose(niw.predictive_logpdf(st1, x), ref, rtol=1e-10)
    # eq. (28) covariance
    assert niw.predictive_cov(st)[0, 0, 0] == pytest.approx(1.25 * 4.0 / (7.0 - 2.0))
    # Monte Carlo: draw Sigma ~ iW, mu | Sigma ~ N, x ~ N(mu, Sigma) -> compare moments with
    # samples of the Student-t predictive
    rng = np.random.default_rng(4)
    d, n = 2, 200_000
    mean0 = np.array([0.1, -0.2])
    lam0 = np.array([[2.0, 0.5], [0.5, 1.0]])
    nu0, g0 = 8.0, 0.5
    sig = sps.invwishart(df=nu0, scale=lam0).rvs(size=n, random_state=rng)
    mu = mean0 + np.einsum("nij,nj->ni", np.linalg.cholesky(g0 * sig), rng.normal(size=(n, d)))
    xs = mu + np.einsum("nij,nj->ni", np.linalg.cholesky(sig), rng.normal(size=(n, d)))
    stn = niw.init_stats(n, mean0, g0, nu0, lam0)
    ts = niw.sample_predictive(stn, rng)
    cov_ref = (1 + g0) * lam0 / (nu0 - d - 1)
    np.testing.assert_allclose(np.cov(xs.T), cov_ref, rtol=0.06, atol=0.01)
    np.testing.assert_allclose(np.cov(ts.T), cov_ref, rtol=0.06, atol=0.01)
    np.testing.assert_allclose(ts.mean(0), mean0, atol=0.02)
    # tails agree too (a Gaussian with the same covariance would not)
    q_ref = np.quantile(xs[:, 0], [0.001, 0.999])
    q_t = np.quantile(ts[:, 0], [0.001, 0.999])
    np.testing.assert_allclose(q_t, q_ref, rtol=0.08)


def test_student_t_sampling_moments_and_kurtosis():
    rng = np.random.default_rng(5)
    n = 400_000
    dof = 6.0
    loc = np.tile([1.0, -2.0], (n, 1))
    shape = np.array([[1.0, 0.3], [0.3, 0.5]])
    chol = np.broadcast_to(niw.cholesky(shape), (n, 2, 2))
    z = rng.standard_normal((n, 2))
    c2 = 2.0 * rng.standard_gamma(dof / 2.0, n)
    x = niw.student_t_from_draws(loc, chol, dof, z, c2)
    np.testing.assert_allclose(x.mean(0), [1.0, -2.0], atol=0.01)
    np.testing.assert_allclose(np.cov(x.T), shape * dof / (dof - 2), rtol=0.03)
    kurt = sps.kurtosis(x[:, 0])
    assert kurt == pytest.approx(6.0 / (dof - 4.0), rel=0.25)  # excess kurtosis of t_6 = 3


@pytest.mark.parametrize("d", [2, 3])
def test_cholesky_closed_form_matches_numpy(d):
    rng = np.random.default_rng(6)
    a = rng.normal(size=(50, d, d))
    spd = a @ a.transpose(0, 2, 1) + np.eye(d)
    np.testing.assert_allclose(niw.cholesky(spd), np.linalg.cholesky(spd), rtol=1e-12)


def test_mmse_mixture_and_stats_from_moments_round_trip():
    st = niw.init_stats(2, np.zeros(2), 0.1, 10.0, np.eye(2) * 7.0, shared=False)
    st.mean[:] = [[1.0, 0.0], [3.0, 2.0]]
    w = np.array([0.25, 0.75])
    est = niw.mmse(st, w)
    np.testing.assert_allclose(est.mean, [2.5, 1.5])
    np.testing.assert_allclose(est.noise_cov, np.eye(2))  # 7 / (10 - 3)
    spread = 0.25 * 0.75 * np.array([[4.0, 4.0], [4.0, 4.0]])
    np.testing.assert_allclose(est.mean_cov, 0.1 * np.eye(2) + spread)
    np.testing.assert_allclose(est.noise_cov_eq30b, 9.0 / 7.0 * 7.0 * np.eye(2) + spread)
    back = niw.stats_from_moments(3, est.mean, 0.2 * np.eye(2), est.noise_cov, 10.0)
    est2 = niw.mmse(back, np.full(3, 1 / 3))
    np.testing.assert_allclose(est2.mean, est.mean)
    np.testing.assert_allclose(est2.noise_cov, est.noise_cov)
    np.testing.assert_allclose(est2.mean_cov, 0.2 * np.eye(2))


def test_take_resamples_all_arrays():
    st = niw.init_stats(3, np.zeros(2), 1.0, 6.0, np.eye(2), shared=False)
    st.mean[:, 0] = [0.0, 1.0, 2.0]
    st.scale[:, 0, 0] = [1.0, 2.0, 3.0]
    st.gamma[:] = [0.1, 0.2, 0.3]
    st.take(np.array([2, 2, 0]))
    np.testing.assert_allclose(st.mean[:, 0], [2.0, 2.0, 0.0])
    np.testing.assert_allclose(st.scale[:, 0, 0], [3.0, 3.0, 1.0])
    np.testing.assert_allclose(st.gamma, [0.3, 0.3, 0.1])


@pytest.mark.parametrize("shared", [True, False])
def test_collapse_keeps_the_mixture_moments(shared: bool) -> None:
    rng = np.random.default_rng(3)
    n, d = 6, 3
    st = niw.init_stats(n, np.zeros(d), 0.05, 12.0, np.eye(d) * 9.0, shared=shared)
    st.mean[:] = rng.normal(scale=0.3, size=(n, d))
    a = rng.normal(size=(n, d, d))
    st.scale[:] = a @ np.swapaxes(a, 1, 2) + 2.0 * np.eye(d)
    if not shared:
        st.gamma[:] = rng.uniform(0.02, 0.1, n)
        st.dof[:] = rng.uniform(10.0, 14.0, n)
    w = rng.dirichlet(np.ones(n))
    before = niw.mmse(st, w)
    niw.collapse(st, w, np.array([1, 2]))
    # every particle carries the mixture's mean and expected noise covariance
    np.testing.assert_allclose(st.mean, np.tile(before.mean, (n, 1)), rtol=1e-14)
    after = niw.mmse(st, rng.dirichlet(np.ones(n)))
    np.testing.assert_allclose(after.mean, before.mean, rtol=1e-14)
    np.testing.assert_allclose(after.noise_cov, before.noise_cov, rtol=1e-12)
    assert float(np.asarray(after.dof)) == pytest.approx(before.dof, rel=1e-14)
    # gamma holds the covariance of the mean (spread included) on average over components 1, 2
    ratio = np.diag(before.mean_cov)[1:] / np.diag(before.noise_cov)[1:]
    np.testing.assert_allclose(st.gamma, np.mean(ratio), rtol=1e-12)
    assert np.all(st.gamma > (0.1 if not shared else 0.05))
    np.testing.assert_allclose(
        np.mean(np.diag(after.mean_cov)[1:] / np.diag(after.noise_cov)[1:]), np.mean(ratio)
    )
