"""The compiled radius-MPF kernels against plain NumPy/Python references."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tire_estimation.core.kernel_random import kernel_state
from tire_estimation.core.radius import kernels as rk
from tire_estimation.core.resampling import normalize_log_weights

R_NOM, TRACK, WHEELBASE = 0.31, 1.55, 2.7


def _pose_reference(east, north, yaw, d3, d4, dt, w3, w4, steer):
    """Eq. (3), (6), (31a) sample by sample with exact cos/sin."""
    east, north, yaw = east.copy(), north.copy(), yaw.copy()
    ds = np.zeros_like(east)
    for j in range(dt.size):
        jj = j if d3.shape[0] > 1 else 0
        ds = 0.5 * dt[j] * (R_NOM * (w3[j] + w4[j]) + w3[j] * d3[jj] + w4[j] * d4[jj])
        if math.isnan(steer[j]):
            dpsi = dt[j] / TRACK * (R_NOM * (w4[j] - w3[j]) + w4[j] * d4[jj] - w3[j] * d3[jj])
        else:
            dpsi = ds * math.tan(steer[j]) / WHEELBASE
        east += ds * np.cos(yaw)
        north += ds * np.sin(yaw)
        yaw += dpsi
    return east, north, yaw, ds / dt[-1]


@pytest.mark.parametrize("case", ["highway", "low_speed_steering"])
def test_pose_propagation_equals_exact_trigonometry(case):
    rng = np.random.default_rng(1)
    n, k = 64, 40
    east, north = rng.normal(0, 10, n), rng.normal(0, 10, n)
    yaw = rng.uniform(-math.pi, math.pi, n)
    d3, d4 = rng.normal(0, 2e-3, (k, n)), rng.normal(0, 2e-3, (k, n))
    dt = np.full(k, 0.01)
    if case == "highway":  # 25 m/s, gentle curve: per-sample heading steps < 0.05 rad
        w3 = np.full(k, 80.0)
        w4 = w3 * 1.003
        steer = np.full(k, np.nan)
    else:  # 2 m/s at full lock with 0.1 s samples: heading steps ~ 0.05 rad and more
        dt = np.full(k, 0.1)
        w3 = w4 = np.full(k, 2.0 / R_NOM)
        steer = np.full(k, 0.6)
        steer[::5] = np.nan
    ref = _pose_reference(east, north, yaw, d3, d4, dt, w3, w4, steer)
    speed = np.zeros(n)
    e, no, y = east.copy(), north.copy(), yaw.copy()
    rk.propagate_pose(e, no, y, speed, d3, d4, dt, w3, w4, steer, R_NOM, TRACK, WHEELBASE)
    np.testing.assert_allclose(e, ref[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(no, ref[1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(y, ref[2], rtol=0, atol=1e-12)
    np.testing.assert_allclose(speed, ref[3], rtol=1e-12)
    moved = np.hypot(e - east, no - north)
    assert np.all(moved > 5.0)  # the test drives somewhere


def test_block_is_draw_then_niw_update_then_pose():
    """propagate_block(learn=True) = draw_block + niw_block_update + propagate_pose."""
    n, k = 30, 7
    rng0 = np.random.default_rng(2)
    mu = 1e-3 * rng0.standard_normal((2, n))
    scale = np.zeros((2, 2, n))
    scale[0, 0] = scale[1, 1] = 7e-6
    scale[0, 1] = scale[1, 0] = 2e-6
    pose = [rng0.normal(0, 1, n) for _ in range(3)] + [np.zeros(n)]
    dt, w3, w4 = np.full(k, 0.01), np.full(k, 70.0), np.full(k, 70.2)
    steer = np.full(k, np.nan)
    lam, gamma, nu = 0.9998, 0.4, 12.0

    a_pose = [p.copy() for p in pose]
    a_mu, a_scale = mu.copy(), scale.copy()
    state = kernel_state(np.random.default_rng(9))
    ga, na = rk.propagate_block(*a_pose, a_mu, a_scale, dt, w3, w4, steer, True, lam, gamma, nu,
                                R_NOM, TRACK, WHEELBASE, state.copy())  # fmt: skip

    b_pose = [p.copy() for p in pose]
    b_mu, b_scale = mu.copy(), scale.copy()
    d3, d4 = rk.draw_block(b_mu, b_scale, lam, gamma, nu, k, state.copy())
    gb, nb = rk.niw_block_update(b_mu, b_scale, d3, d4, lam, gamma, nu)
    rk.propagate_pose(*b_pose, d3, d4, dt, w3, w4, steer, R_NOM, TRACK, WHEELBASE)
    for x, y in zip([*a_pose, a_mu, a_scale], [*b_pose, b_mu, b_scale], strict=True):
        np.testing.assert_array_equal(x, y)
    assert (ga, na) == (gb, nb)
    assert not np.array_equal(a_mu, mu)  # the statistics were updated


def test_reweight_matches_normalized_log_weights():
    rng = np.random.default_rng(3)
    n = 200
    w = rng.dirichlet(np.ones(n))
    w[:5] = 0.0  # dead particles stay dead
    h = rng.normal(0, 3, (2, n))
    y0, y1 = 0.5, -0.2
    r = np.array([[2.0, 0.3], [0.3, 1.5]])
    d = np.array([y0, y1])[:, None] - h
    maha = np.einsum("in,ij,jn->n", d, np.linalg.inv(r), d)
    with np.errstate(divide="ignore"):
        log_w = (
            np.log(w) - 0.5 * maha - 0.5 * (2 * math.log(2 * math.pi) + math.log(np.linalg.det(r)))
        )
    ref_w, ref_lz = normalize_log_weights(log_w)
    got = w.copy()
    lz, n_eff = rk.fix_reweight(got, h, y0, y1, r[0, 0], r[0, 1], r[1, 1])
    np.testing.assert_allclose(got, ref_w, rtol=1e-12, atol=1e-300)
    assert lz == pytest.approx(ref_lz, rel=1e-12)
    assert n_eff == pytest.approx(1.0 / np.sum(ref_w**2), rel=1e-12)
    assert np.all(got[:5] == 0.0)
    # no finite weight left: uniform weights, -inf evidence
    dead = np.zeros(n)
    lz, n_eff = rk.fix_reweight(dead, h, y0, y1, r[0, 0], r[0, 1], r[1, 1])
    assert lz == -np.inf and n_eff == pytest.approx(n)
    np.testing.assert_allclose(dead, 1.0 / n)


def test_moments_match_numpy_with_headings_across_pi():
    rng = np.random.default_rng(4)
    n = 300
    w = rng.dirichlet(np.ones(n))
    east, north = rng.normal(5, 2, n), rng.normal(-3, 1, n)
    yaw = math.pi + rng.normal(0, 0.05, n) + 2 * math.pi * rng.integers(-2, 3, n)  # wraps
    mu = rng.normal(0, 1e-3, (2, n))
    scale = rng.uniform(1e-6, 2e-6, (2, 2, n))
    scale[1, 0] = scale[0, 1]
    pose, cov, m, spread, lw = rk.moments(east, north, yaw, mu, scale, w)
    yc = math.atan2(w @ np.sin(yaw), w @ np.cos(yaw))
    u = np.mod(yaw - yc + math.pi, 2 * math.pi) + yc - math.pi
    x = np.stack([east, north, u])
    mean = x @ w
    dev = x - mean[:, None]
    np.testing.assert_allclose(pose[:2], mean[:2], rtol=1e-12)
    assert math.cos(pose[2] - mean[2]) == pytest.approx(1.0, abs=1e-12)
    assert -math.pi <= pose[2] <= math.pi
    np.testing.assert_allclose(cov, (dev * w) @ dev.T, rtol=1e-9)
    assert cov[2, 2] == pytest.approx(0.05**2, rel=0.3)  # not inflated by the 2 pi jumps
    np.testing.assert_allclose(m, mu @ w, rtol=1e-12)
    e = mu - (mu @ w)[:, None]
    np.testing.assert_allclose(spread, (e * w) @ e.T, rtol=1e-9)
    np.testing.assert_allclose(lw, np.einsum("abn,n->ab", scale, w), rtol=1e-12)


def test_fix_prediction_without_noise_is_eq13():
    rng = np.random.default_rng(5)
    n = 50
    east, north, yaw = rng.normal(0, 5, n), rng.normal(0, 5, n), rng.uniform(-3, 3, n)
    speed = rng.uniform(20, 30, n)
    mu = np.zeros((2, n))
    w = rng.dirichlet(np.ones(n))
    before = east.copy()
    no_bias = np.zeros((2, n))
    st = kernel_state(np.random.default_rng(0))
    h, mean, cov = rk.fix_predict(east, north, yaw, speed, mu, w, 0.0, 0.0, 0.0, 1.2, -0.4, 0.1,
                                  st, no_bias, 1.0, False)  # fmt: skip
    lx = 1.2 + 0.1 * speed
    ref = np.stack([east + lx * np.cos(yaw) + 0.4 * np.sin(yaw),
                    north + lx * np.sin(yaw) - 0.4 * np.cos(yaw)])  # fmt: skip
    np.testing.assert_allclose(h, ref, rtol=1e-13)
    np.testing.assert_allclose(mean, ref @ w, rtol=1e-12)
    dev = ref - (ref @ w)[:, None]
    np.testing.assert_allclose(cov, (dev * w) @ dev.T, rtol=1e-9)
    np.testing.assert_array_equal(east, before)  # no pose noise requested, none applied
    # with pose noise: positions move by about the requested std
    rk.fix_predict(east, north, yaw, speed, mu, w, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0,
                   kernel_state(np.random.default_rng(0)), no_bias, 1.0, False)  # fmt: skip
    assert np.std(east - before) == pytest.approx(0.5, rel=0.3)


def test_fix_prediction_with_the_gnss_bias_adds_the_propagated_means():
    """``with_bias``: b = phi b in place, h + b, and the moments are those of h + b."""
    rng = np.random.default_rng(8)
    n = 40
    east, north, yaw = rng.normal(0, 5, n), rng.normal(0, 5, n), rng.uniform(-3, 3, n)
    speed, mu, w = rng.uniform(20, 30, n), np.zeros((2, n)), rng.dirichlet(np.ones(n))
    bias = rng.normal(0.0, 1.0, (2, n))
    b0 = bias.copy()
    args = (east, north, yaw, speed, mu, w, 0.0, 0.0, 0.0, 0.5, 0.2, 0.0)
    h0, _, _ = rk.fix_predict(*args, kernel_state(np.random.default_rng(0)), bias, 0.9, False)
    np.testing.assert_array_equal(bias, b0)  # off: untouched
    h, mean, cov = rk.fix_predict(*args, kernel_state(np.random.default_rng(0)), bias, 0.9, True)
    np.testing.assert_allclose(bias, 0.9 * b0, rtol=1e-15)
    ref = h0 + 0.9 * b0
    np.testing.assert_allclose(h, ref, rtol=1e-13)
    np.testing.assert_allclose(mean, ref @ w, rtol=1e-12)
    dev = ref - (ref @ w)[:, None]
    np.testing.assert_allclose(cov, (dev * w) @ dev.T, rtol=1e-9)


def test_bias_correct_is_the_kalman_update_of_every_mean():
    rng = np.random.default_rng(9)
    bias, h = rng.normal(0, 1, (2, 30)), rng.normal(0, 2, (2, 30))
    k = np.array([[0.3, 0.05], [-0.02, 0.4]])
    y = np.array([0.7, -1.1])
    ref = bias + k @ (y[:, None] - h)
    rk.bias_correct(bias, h, y[0], y[1], k[0, 0], k[0, 1], k[1, 0], k[1, 1])
    np.testing.assert_allclose(bias, ref, rtol=1e-14, atol=1e-15)


def test_velocity_likelihood_matches_the_per_particle_gaussian():
    """:func:`velocity_predict` + :func:`loglik_reweight` against the model of
    ``RadiusMPF.update_velocity`` written with NumPy 2x2 matrices: ``h_i = R(psi_i + offset)
    [v_i - r l_y, r l_x]``, ``S_i = R + q n n' + p_i t t'``, weights ``w_i N(y; h_i, S_i)``."""
    rng = np.random.default_rng(11)
    n = 300
    yaw = 0.4 + 0.02 * rng.standard_normal(n)
    mu = 1e-3 * rng.standard_normal((2, n))
    lam = np.empty((2, 2, n))
    for i in range(n):
        a = 1e-4 * rng.standard_normal((2, 3))
        lam[:, :, i] = a @ a.T + 1e-9 * np.eye(2)
    w = rng.dirichlet(np.ones(n))
    w[:3] = 0.0
    w3, w4, off, yr, lx, ly, q, k_sigma, along = 80.0, 80.5, -0.01, 0.05, 1.2, 0.3, 0.04, 0.1, 0.01
    r = np.array([[0.01, 0.002], [0.002, 0.012]])
    v_virt = 0.5 * R_NOM * (w3 + w4)
    y = np.array([23.0, 10.5])
    h = np.empty((2, n))
    maha_ref = np.empty(n)
    logdet_ref = np.empty(n)
    s_sum = np.zeros((2, 2))
    for i in range(n):
        psi = yaw[i] + off
        t = np.array([math.cos(psi), math.sin(psi)])
        nn = np.array([-math.sin(psi), math.cos(psi)])
        v = v_virt + 0.5 * (w3 * mu[0, i] + w4 * mu[1, i])
        ww = np.array([w3, w4])
        p = k_sigma * ww @ lam[:, :, i] @ ww + along
        rot = np.array([[t[0], nn[0]], [t[1], nn[1]]])
        h[:, i] = rot @ np.array([v - yr * ly, yr * lx])
        s_i = r + q * np.outer(nn, nn) + p * np.outer(t, t)
        d = y - h[:, i]
        maha_ref[i] = d @ np.linalg.solve(s_i, d)
        logdet_ref[i] = math.log(np.linalg.det(s_i))
        s_sum += w[i] * s_i
    m = h @ w
    e = h - m[:, None]
    s_ref = (e * w) @ e.T + s_sum
    maha, logdet = np.empty(n), np.empty(n)
    m0, m1, s00, s01, s11 = rk.velocity_predict(
        yaw, off, mu, lam, w, v_virt, w3, w4, k_sigma, along, yr, lx, ly, q,
        r[0, 0], r[0, 1], r[1, 1], y[0], y[1], maha, logdet,
    )  # fmt: skip
    np.testing.assert_allclose([m0, m1], m, rtol=1e-13)
    np.testing.assert_allclose([[s00, s01], [s01, s11]], s_ref, rtol=1e-9)
    np.testing.assert_allclose(maha, maha_ref, rtol=1e-9)
    np.testing.assert_allclose(logdet, logdet_ref, rtol=1e-12, atol=1e-12)
    with np.errstate(divide="ignore"):
        log_w = np.log(w) - 0.5 * (maha_ref + logdet_ref) - math.log(2 * math.pi)
    ref_w, ref_lz = normalize_log_weights(log_w)
    got = w.copy()
    lz, n_eff = rk.loglik_reweight(got, maha, logdet)
    np.testing.assert_allclose(got, ref_w, rtol=1e-9, atol=1e-300)
    assert lz == pytest.approx(ref_lz, rel=1e-9)
    assert n_eff == pytest.approx(1.0 / np.sum(ref_w**2), rel=1e-9)
    assert np.all(got[:3] == 0.0)
    # a particle whose S is not positive definite gets weight zero
    logdet[5] = np.nan
    got = w.copy()
    rk.loglik_reweight(got, maha, logdet)
    assert got[5] == 0.0 and got.sum() == pytest.approx(1.0)
