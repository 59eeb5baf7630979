"""Information bound on the cornering stiffnesses (``evaluation/stiffness_bound.py``, issue 5).

Measured on snow drives 0-1 from their activation (docs/results.md section 6): rear 2.0 % after
1 s and 1.1 % after 2 s with a constant stiffness; 4.1 % and 2.5 % with the filter's noise model
(``stiffness_noise_std_fraction`` 0.03).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import tire_estimation.evaluation.stiffness as ev
from tire_estimation.core.stiffness.estimator import StiffnessEstimator
from tire_estimation.evaluation.stiffness_bound import (
    BoundNoise,
    bound_noise,
    deterministic_crlb,
    drive_signals,
    posterior_bound,
)

STUDY = {
    "niw_update": "rao_blackwellized",
    "friction_coefficient": 0.3,
    "tyre_shape": "magic_formula",
    "magic_formula_curvature_e": -0.5,
}


@pytest.fixture(scope="module")
def snow() -> tuple:
    """Snow drive 0, the filter's parameters and the first steered sample (|delta| > 3 mrad)."""
    sim = ev.simulate("snow_sine", seed=0, sensors=ev.NO_BIAS)
    cfg = ev.eval_config(200, **STUDY)
    p = StiffnessEstimator(cfg, sim.vehicle, np.random.default_rng(0)).params
    sig = drive_signals(sim, p.wheel_radius_m)
    k0 = int(np.argmax(np.abs(sig.delta_rad) > 0.003))
    return cfg, p, sig, k0


def test_drive_signals_are_the_truth_on_the_imu_grid(snow: tuple) -> None:
    _, p, sig, _ = snow
    assert sig.t_s[0] == 0.0 and np.all(np.diff(sig.t_s) > 0.0)
    # snow: the true cornering stiffness is half the vehicle's nominal (the study's scaling)
    np.testing.assert_allclose(sig.stiffness_n_rad[-1, 1:] / np.asarray(p.nominal)[1:], 0.5)
    # straight driving at the start of the sine drive, then steering
    assert abs(sig.delta_rad[0]) < 0.003 and np.max(np.abs(sig.delta_rad)) > 0.02
    assert np.median(sig.vx_m_s) == pytest.approx(15.0, rel=0.05)


def test_without_process_noise_the_bound_is_the_cramer_rao_bound(snow: tuple) -> None:
    """With Sigma = 0, no jitter and an uninformative prior, the Kalman form along the truth and
    the batch Fisher information of the simulated outputs agree."""
    cfg, p, sig, k0 = snow
    quiet = BoundNoise(
        stiffness_noise_std_n_rad=np.zeros(3),
        jitter_vy_m_s_sqrt_s=0.0,
        jitter_yaw_rate_rad_s_sqrt_s=0.0,
        ay_std_m_s2=cfg.accel_noise_std_m_s2,
        gyro_std_rad_s=cfg.gyro_noise_std_rad_s,
        prior_std=np.array([10.0, 10.0, 1e7, 1e7]),
    )
    (kalman,) = posterior_bound(sig, p, k0, [1.0], quiet)
    batch = np.sqrt(
        np.diag(
            deterministic_crlb(sig, p, k0, 1.0, cfg.accel_noise_std_m_s2, cfg.gyro_noise_std_rad_s)
        )[2:]
    )
    np.testing.assert_allclose(kalman, batch, rtol=0.03)
    # the rear is the weaker axle on this drive: its std is more than the front's
    assert batch[1] > 1.5 * batch[0]


def test_the_bound_narrows_with_time_and_widens_with_the_stiffness_noise(snow: tuple) -> None:
    cfg, p, sig, k0 = snow
    times = [0.5, 1.0, 2.0]
    nominal = np.asarray(p.nominal)
    std = {}
    for frac in (0.01, 0.03):
        c = dataclasses.replace(cfg, stiffness_noise_std_fraction=frac)
        noise = bound_noise(c, nominal, 0.3, 0.0175)
        np.testing.assert_allclose(noise.stiffness_noise_std_n_rad, frac * nominal)
        std[frac] = posterior_bound(sig, p, k0, times, noise)
    for s in std.values():
        assert np.all(np.isfinite(s))
        assert np.all(np.diff(s, axis=0) < 0.0)
    assert np.all(std[0.03] > std[0.01])
    # after 2 s the noise costs the rear more than a third of its information's std
    assert std[0.03][2, 1] > 1.3 * std[0.01][2, 1]
    # rear, % of the truth, after 2 s: the filter's own noise model allows no better than ~2.5 %
    rear_2s = 100.0 * std[0.03][2, 1] / sig.stiffness_n_rad[k0, 2]
    assert 1.5 < rear_2s < 4.0


def test_bad_input_is_refused_with_the_name_of_the_value(snow: tuple) -> None:
    cfg, p, sig, k0 = snow
    noise = bound_noise(cfg, np.asarray(p.nominal), 0.3, 0.0175)
    with pytest.raises(ValueError, match="k0"):
        posterior_bound(sig, p, len(sig.t_s), [1.0], noise)
    with pytest.raises(ValueError, match="prior_std"):
        posterior_bound(sig, p, k0, [1.0], dataclasses.replace(noise, prior_std=np.zeros(4)))
    with pytest.raises(ValueError, match="duration_s"):
        deterministic_crlb(sig, p, k0, 0.0, 0.05, 0.00175)
    # a time after the end of the drive is NaN, the others are given in ascending order
    late = posterior_bound(sig, p, len(sig.t_s) - 300, [1.0, 0.5, 100.0], noise)
    assert np.all(np.isfinite(late[:2])) and np.all(np.isnan(late[2]))
    assert np.all(late[1] <= late[0]) and late[1, 0] < late[0, 0]
