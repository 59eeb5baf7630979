"""AUG-KF baseline (eq. 10-11) on the synthetic drive."""

from __future__ import annotations

import numpy as np
import pytest

from tests.core.radius.test_mpf import R_NOM, TRACK, TRUE_REAR_ERR, WHEELBASE, make_drive
from tire_estimation.core.radius.aug_kf import AugKf
from tire_estimation.core.radius.model import RadiusMotionModel


def _kf():
    return AugKf(
        RadiusMotionModel(R_NOM, TRACK, WHEELBASE), np.zeros(2), 3e-3, 1e-3, 2e-5, 0.01, 0.002
    )


@pytest.mark.parametrize(("rate_hz", "duration_s"), [(1.0, 300.0), (10.0, 150.0)])
def test_aug_kf_converges(rate_hz, duration_s):
    drive = make_drive(duration_s=duration_s, gnss_rate_hz=rate_hz, seed=4)
    kf = _kf()
    kf.init_pose(
        np.array([drive["east"][0], drive["north"][0], drive["yaw"][0]]), np.diag([1, 1, 0.01])
    )
    fix_at = dict(zip(drive["gi"].tolist(), range(drive["gi"].size), strict=False))
    r = np.eye(2) * drive["gnss_std"] ** 2
    nis = []
    for k in range(1, drive["t"].size):
        kf.predict(0.01, drive["ws"][k - 1])
        if k in fix_at:
            upd, hj = kf.innovation(drive["gnss"][fix_at[k]], r, np.zeros(2))
            nis.append(upd.nis)
            kf.update(upd, hj)
    err = kf.x[3:] - np.array(TRUE_REAR_ERR)
    assert np.all(np.abs(err) < 0.5e-3), err
    assert np.all(np.sqrt(np.diag(kf.p)[3:]) < 0.5e-3)
    assert np.hypot(kf.x[0] - drive["east"][-1], kf.x[1] - drive["north"][-1]) < 3.0
    assert 1.0 < np.mean(nis[20:]) < 3.5  # 2 dof: consistent innovations


def test_jacobian_matches_finite_differences():
    kf = _kf()
    kf.x[:] = [1.0, 2.0, 0.7, 1e-3, -2e-3]
    ws = np.array([80.0, 80.5, 80.2, 80.9])

    def f(x):
        k = _kf()
        k.x[:] = x
        k.predict(0.05, ws)
        return k.x.copy()

    k = _kf()
    k.x[:] = kf.x
    k.p = np.zeros((5, 5))
    # P = 0 and zero noise -> P after predict = Q; use the state Jacobian via finite differences
    jac = np.zeros((5, 5))
    for j in range(5):
        dx = np.zeros(5)
        dx[j] = 1e-7
        jac[:, j] = (f(kf.x + dx) - f(kf.x - dx)) / 2e-7
    k2 = _kf()
    k2.x[:] = kf.x
    k2.p = np.eye(5)
    k2.w_var = k2.rw_q = k2.pos_q = k2.yaw_q = 0.0
    k2.predict(0.05, ws)
    np.testing.assert_allclose(k2.p, jac @ jac.T, rtol=1e-5, atol=1e-9)


def test_paused_predict_freezes_radii_and_update_keeps_them():
    kf = _kf()
    kf.init_pose(np.zeros(3), np.eye(3))
    kf.predict(0.01, np.array([80.0, 80.0, 80.0, 80.0]), learn=False)
    upd, hj = kf.innovation(np.array([5.0, 0.0]), np.eye(2), np.zeros(2))
    kf.update(upd, hj, learn=False)
    np.testing.assert_array_equal(kf.x[3:], [0.0, 0.0])
    assert kf.x[0] > 0.5


def test_gnss_bias_states_are_the_kalman_filter_of_a_gauss_markov_error():
    """Standing still at a known pose, the two appended bias states follow the scalar Kalman
    filter of a first-order Gauss-Markov error; without the bias the state has 5 entries."""
    assert _kf().nx == 5
    sb, tau, dt = 1.0, 60.0, 0.1
    kf = AugKf(
        RadiusMotionModel(R_NOM, TRACK, WHEELBASE), np.zeros(2), 3e-3, 1e-3, 0.0, 0.0, 0.0,
        gnss_bias_std_m=sb, gnss_bias_time_constant_s=tau,
    )  # fmt: skip
    assert kf.nx == 7
    kf.init_pose(np.zeros(3), np.eye(3) * 1e-16)
    r = np.diag([1.5**2, 2.0**2])
    rw = np.diag(r) - sb**2
    b_ref, p_ref = np.zeros(2), np.full(2, sb**2)
    phi = np.exp(-dt / tau)
    rng = np.random.default_rng(4)
    for _ in range(30):
        for _ in range(10):
            kf.predict(dt, np.zeros(4), learn=False)
        y = rng.normal(0.0, 1.5, 2) + np.array([0.7, -0.4])
        upd, hj = kf.innovation(y, r, np.zeros(2))
        b_ref = phi**10 * b_ref
        p_ref = phi**20 * p_ref + sb**2 * (1 - phi**20)
        np.testing.assert_allclose(np.diag(upd.innovation_cov_m2), p_ref + rw, rtol=1e-9)
        kf.update(upd, hj, learn=False)
        k = p_ref / (p_ref + rw)
        b_ref = b_ref + k * (y - b_ref)
        p_ref = (1 - k) * p_ref
        np.testing.assert_allclose(kf.x[5:], b_ref, atol=1e-7)
        np.testing.assert_allclose(np.diag(kf.p)[5:], p_ref, rtol=1e-6)
    np.testing.assert_array_equal(kf.x[3:5], 0.0)  # learn=False: radii untouched


def test_gnss_bias_fraction_equals_the_fixed_size_for_a_constant_covariance():
    """sigma_b^2 = f lambda_min(R): f = 0.4 of R = diag(2.5, 4) is the 1 m of a fixed model."""
    model = RadiusMotionModel(R_NOM, TRACK, WHEELBASE)
    fixed = AugKf(model, np.zeros(2), 3e-3, 1e-3, 0.0, 0.0, 0.0, gnss_bias_std_m=1.0)
    frac = AugKf(model, np.zeros(2), 3e-3, 1e-3, 0.0, 0.0, 0.0, gnss_bias_fraction=0.4)
    assert frac.nx == 7
    r = np.diag([2.5, 4.0])
    frac.observe_fix_cov(r)
    for kf in (fixed, frac):
        kf.init_pose(np.zeros(3), np.eye(3) * 1e-16)
    rng = np.random.default_rng(6)
    for _ in range(20):
        y = rng.normal(0.0, 1.5, 2)
        for kf in (fixed, frac):
            for _ in range(10):
                kf.predict(0.1, np.zeros(4), learn=False)
            kf.observe_fix_cov(r)
            upd, hj = kf.innovation(y, r, np.zeros(2))
            kf.update(upd, hj, learn=False)
        np.testing.assert_allclose(frac.x, fixed.x, atol=1e-12)
        np.testing.assert_allclose(frac.p, fixed.p, atol=1e-12)
    assert abs(frac.x[5]) > 0.05  # the bias states did move


def test_velocity_jacobian_matches_finite_differences():
    """H of the Doppler velocity (beyond the paper) against central differences of h."""
    model = RadiusMotionModel(0.31, 1.55, 2.7)
    kf = AugKf(model, np.array([1e-3, -1e-3]), 2e-3, 1e-3, 2e-5, 0.01, 0.002)
    kf.x[:3] = [10.0, -4.0, 0.7]
    lever, ws = np.array([1.5, 0.4]), (70.0, 72.0)
    r = np.eye(2) * 0.01

    def h(x):
        kf.x = x.copy()
        upd, _ = kf.velocity_innovation(np.zeros(2), r, lever, 0.2, ws)
        return -upd.innovation_m

    x0 = kf.x.copy()
    _, hj = kf.velocity_innovation(np.zeros(2), r, lever, 0.2, ws)
    num = np.zeros_like(hj)
    for j, step in ((2, 1e-6), (3, 1e-7), (4, 1e-7)):
        e = np.zeros(5)
        e[j] = step
        num[:, j] = (h(x0 + e) - h(x0 - e)) / (2 * step)
    np.testing.assert_allclose(hj, num, rtol=1e-6, atol=1e-9)


def test_velocity_heading_offset_equals_a_rotated_heading():
    """``heading_offset_rad``: the prediction and Jacobian are those of the heading psi +
    offset (the velocity's time)."""
    model = RadiusMotionModel(0.31, 1.55, 2.7)
    kf = AugKf(model, np.array([1e-3, -1e-3]), 2e-3, 1e-3, 2e-5, 0.01, 0.002)
    kf.x[:3] = [10.0, -4.0, 0.7]
    lever, ws, r = np.array([1.5, 0.4]), (70.0, 72.0), np.eye(2) * 0.01
    y = np.array([15.0, 14.0])
    upd, hj = kf.velocity_innovation(y, r, lever, 0.2, ws, heading_offset_rad=-0.03)
    kf.x[2] = 0.67
    ref, hj_ref = kf.velocity_innovation(y, r, lever, 0.2, ws)
    np.testing.assert_allclose(upd.innovation_m, ref.innovation_m, rtol=1e-12)
    np.testing.assert_allclose(upd.innovation_cov_m2, ref.innovation_cov_m2, rtol=1e-12)
    np.testing.assert_allclose(hj, hj_ref, rtol=1e-12)
