"""The radius estimator's persisted state: an implausible or malformed state is rejected by
name and changes nothing; a valid one restores and the filter runs on finite."""

from __future__ import annotations

import copy
import json
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from tests.core.radius.test_estimator import VEH, feed
from tests.core.radius.test_mpf import make_drive
from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.radius.estimator import RadiusEstimator
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import InputError

State = dict[str, Any]


def _est(run_aug_kf: bool = True, vehicle: VehicleParams = VEH) -> RadiusEstimator:
    cfg = RadiusEstimatorConfig(n_particles=100, run_aug_kf=run_aug_kf)
    return RadiusEstimator(cfg, vehicle, np.random.default_rng(3))


def _good() -> State:
    state = json.loads(json.dumps(_est().state_dict()))
    state["rear"]["mean_m"] = [1e-3, -0.5e-3]
    state["rear"]["dof"] = 250.0
    return state


GOOD = _good()


def _with(path: str, value: Any) -> Callable[[State], None]:
    def change(state: State) -> None:
        *keys, last = path.split(".")
        d = state
        for k in keys:
            d = d[k]
        d[last] = value

    return change


BAD: list[tuple[str, Callable[[State], None], str]] = [
    ("zero noise covariance", _with("rear.noise_cov_m2", [[0, 0], [0, 0]]),
     "not positive definite"),
    ("negative noise covariance", _with("rear.noise_cov_m2", [[-1e-6, 0], [0, -1e-6]]),
     "not positive definite"),
    ("dof 1e308", _with("rear.dof", 1e308), "dof"),
    ("dof a 500-digit integer", _with("rear.dof", int("9" * 500)), "too large"),
    ("mean +100 mm", _with("rear.mean_m", [0.1, 0.0]), "outside"),
    ("mean -100 mm", _with("rear.mean_m", [0.0, -0.1]), "outside"),
    ("mean 1e308 m", _with("rear.mean_m", [1e308, 1e308]), "outside"),
    ("NaN mean", _with("rear.mean_m", [float("nan"), 0.0]), "not finite"),
    ("indefinite mean covariance", _with("rear.mean_cov_m2", [[1e-6, 2e-6], [2e-6, 1e-6]]),
     "not positive definite"),
    ("aug_kf of the wrong shape", _with("aug_kf.mean_m", [0.0]), "aug_kf.mean_m"),
    ("aug_kf covariance zero", _with("aug_kf.cov_m2", [[0, 0], [0, 0]]), "aug_kf.cov_m2"),
    ("extra key", _with("rear.extra", 1), "unknown keys extra"),
    ("no version", lambda s: s.pop("version"), "lacks version"),
]  # fmt: skip


@pytest.mark.parametrize(("change", "reason"), [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_an_implausible_state_is_rejected_and_changes_nothing(
    change: Callable[[State], None], reason: str
) -> None:
    est = _est()
    before = est.state_dict()
    kf_before = est.kf.x.copy() if est.kf is not None else None
    state = copy.deepcopy(GOOD)
    change(state)
    with pytest.raises(InputError, match=reason) as info:
        est.load_state_dict(state)
    assert info.value.kind == "state"
    assert est.state_dict() == before
    assert est.kf is not None and np.array_equal(est.kf.x, kf_before)


def test_after_a_rejection_the_filter_learns_on_finite() -> None:
    """A zero noise covariance, once accepted, left the filter NaN (published as 0.000 mm while
    running); rejected, the filter keeps its prior and learns."""
    est = _est(run_aug_kf=False)
    state = copy.deepcopy(GOOD)
    state["rear"]["noise_cov_m2"] = [[0.0, 0.0], [0.0, 0.0]]
    with pytest.raises(InputError):
        est.load_state_dict(state)
    drive = make_drive(duration_s=30.0, gnss_rate_hz=1.0, seed=4)
    feed(est, drive)
    e = est.estimate()
    assert e.state in ("running", "paused")
    st = est.mpf.stats
    assert all(np.all(np.isfinite(a)) for a in (st.mean, st.scale, st.gamma, st.dof))
    assert np.all(np.abs(e.radius_error_m) < 0.01) and np.all(e.radius_error_std_m < 0.01)


def test_a_valid_state_restores_and_the_band_follows_the_nominal_radius() -> None:
    est = _est()
    est.load_state_dict(GOOD)
    np.testing.assert_allclose(est.estimate().radius_error_m, [1e-3, -0.5e-3], atol=1e-4)
    # 100 mm on a 0.5 m tyre is within its band (125 mm)
    big = VehicleParams(name=VEH.name, nominal_tire_radius_m=0.5)
    state = copy.deepcopy(GOOD)
    state["rear"]["mean_m"] = [0.1, 0.0]
    est = _est(vehicle=big)
    est.load_state_dict(state)
    assert est.estimate().radius_error_m[0] == pytest.approx(0.1, abs=1e-4)
    # a prior std configured above the band still restores (a state saved before learning)
    wide = RadiusEstimatorConfig(n_particles=100, prior_radius_error_std_m=0.03)
    est = RadiusEstimator(wide, VEH, np.random.default_rng(0))
    est.load_state_dict(json.loads(json.dumps(est.state_dict())))


@pytest.mark.parametrize("wheels", ["rear", "all"])
def test_radius_errors_are_those_of_the_estimate(wheels: str) -> None:
    """At every wheel-speed sample, fixes or not (queued predictions), learning or not."""
    drive = make_drive(duration_s=40.0, gnss_rate_hz=1.0, seed=2)
    est = RadiusEstimator(
        RadiusEstimatorConfig(n_particles=100, wheels=wheels), VEH, np.random.default_rng(3)
    )
    seen: list[bool] = []

    def check(k: int, t: int) -> None:
        e = est.estimate()
        names, errors, stds, active = est.radius_errors()
        assert names == e.wheels
        assert errors == e.radius_error_m.tolist()
        assert stds == e.radius_error_std_m.tolist()
        assert active == list(e.active)
        seen.append(bool(e.active[-1]))

    feed(est, drive, hook=check)
    assert len(est.radius_errors()[0]) == (4 if wheels == "all" else 2)
    assert any(seen) and not all(seen)
