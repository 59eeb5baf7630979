"""One front-end for every stiffness filter (``core/stiffness/frontend.py``): the same inputs give
Algorithm 1 and any other filter the same measurements and learning flags."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import tire_estimation.core as core_pkg
from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.core.stiffness.estimator import StiffnessEstimator
from tire_estimation.core.stiffness.filter import (
    BaselineConfig,
    FilterEstimate,
    Measurement,
    StiffnessFilter,
)
from tire_estimation.core.stiffness.frontend import StiffnessFrontEnd
from tire_estimation.core.vehicle import VehicleParams

MS = 1_000_000


class _Log(StiffnessFilter):
    """Logs (learn, learn_cx, measurement) of every update."""

    def __init__(self) -> None:
        self.log: list[tuple[bool, bool, Measurement]] = []

    def initialize(self, x0: Any, x0_std: Any) -> None:
        self.initialized = True
        self.x0 = np.asarray(x0, dtype=float)

    def predict(self, dt_s: float, learn: bool, learn_cx: bool) -> None:
        pass

    def update(self, meas: Measurement, learn: bool, learn_cx: bool) -> None:
        self.log.append((learn, learn_cx, meas))

    def estimate(self) -> FilterEstimate:
        return FilterEstimate(
            stiffness=np.ones(3),
            stiffness_std=np.zeros(3),
            state=self.x0,
            state_cov=np.eye(3),
            n_eff=float("nan"),
        )


class _LogFrontEnd(StiffnessFrontEnd[_Log]):
    def make_filter(self) -> _Log:
        return _Log()


class _MpfLog:
    """Stands in for ``StiffnessMpf`` (its call signature); keeps the inputs of every update."""

    def __init__(self) -> None:
        self.initialized = False
        self.steps: list[tuple[bool, bool, tuple[Any, ...]]] = []

    def initialize(self, x0: Any, x0_std: Any, bias0: Any = None) -> None:
        self.initialized = True

    def predict(self, dt_s: float, learn: bool, learn_cx: bool | None = None) -> None:
        pass

    def update(
        self,
        y: Any,
        delta_rad: float,
        wheel_speed_m_s: Any,
        learn: bool,
        vx_m_s: float | None = None,
        learn_cx: bool | None = None,
    ) -> None:
        self.steps.append((learn, learn_cx, (tuple(y), delta_rad, wheel_speed_m_s, vx_m_s)))


def _drive(est: Any, wheels: bool, n: int = 600) -> list[tuple[bool, bool, str]]:
    """20 m/s with steering and a varying ax from 1 s on; wheel speeds or a measured speed.
    Returns (active, cx_active, reason) after every IMU sample."""
    out = []
    w = 20.0 / 0.31
    for k in range(n):
        t = 1_000_000_000 + k * 10 * MS
        if wheels:
            est.on_wheel_speeds(t, [w, w, w, w])
        else:
            est.on_velocity(t, 20.0)
        est.on_steering(t + 1, 0.02 if k >= 100 else 0.0)
        ax = 0.5 * np.sin(0.05 * k) if k >= 100 else 0.0
        est.on_imu(t + 2, [0.0, 0.0, 0.01], [ax, 0.3, 9.81])
        out.append((est._active, est._cx_active, est._reason))
    return out


def _front_end(**kw: Any) -> _LogFrontEnd:
    return _LogFrontEnd(BaselineConfig(**kw), VehicleParams(), np.random.default_rng(0))


def _algorithm_1() -> StiffnessEstimator:
    est = StiffnessEstimator(
        StiffnessEstimatorConfig(n_particles=4), VehicleParams(), np.random.default_rng(0)
    )
    est.mpf = _MpfLog()  # type: ignore[assignment]
    return est


@pytest.mark.parametrize("wheels", [True, False])
def test_algorithm_1_and_another_filter_see_the_same_steps(wheels: bool) -> None:
    alg1, other = _algorithm_1(), _front_end()
    flags = _drive(alg1, wheels)
    assert flags == _drive(other, wheels)
    a_log = alg1.mpf.steps  # type: ignore[attr-defined]
    o_log = other.filter.log
    assert [f[:2] for f in a_log] == [f[:2] for f in o_log]
    for (_, _, (y, delta, speeds, vx)), (_, _, meas) in zip(a_log, o_log, strict=True):
        assert y == tuple(meas.y)
        assert (delta, speeds) == (meas.delta_rad, meas.wheel_speed_m_s)
        assert vx == (meas.speed_m_s if meas.vx_measured else None)
    assert any(active for active, _, _ in flags)


def test_cx_is_learned_only_with_wheel_speeds() -> None:
    # with wheel speeds a varying ax excites Cx; a measured speed leaves the slip (eq. 3)
    # unknown, so Cx stays frozen for every filter
    with_wheels = _drive(_front_end(), wheels=True)
    assert any(cx for _, cx, _ in with_wheels)
    measured = _drive(_front_end(), wheels=False)
    assert not any(cx for _, cx, _ in measured)
    assert measured[-1] == (True, False, "excited (Cx frozen: no wheel speeds)")


def test_the_measurement_and_the_initial_state() -> None:
    est = _front_end()
    _drive(est, wheels=False, n=10)
    meas = est.filter.log[-1][2]
    assert meas.vx_measured and meas.speed_m_s == 20.0
    assert meas.wheel_speed_m_s == (20.0, 20.0)
    # eq. (12) y = [ax, ay, r]
    np.testing.assert_allclose(meas.y, [0.0, 0.3, 0.01])
    np.testing.assert_allclose(est.filter.x0, [20.0, 0.0, 0.01])
    e = est.estimate()
    assert e.vx_m_s == 20.0 and e.mean_log_predictive is None


def test_losing_the_speed_stops_learning_of_cx_too() -> None:
    est = _front_end()
    flags = _drive(est, wheels=True)
    assert flags[-1][:2] == (True, True)
    t = 1_000_000_000 + 600 * 10 * MS + 500 * MS
    est.on_imu(t, [0.0, 0.0, 0.0], [0.0, 0.0, 9.81])
    assert (est._active, est._cx_active, est._reason) == (False, False, "no speed input")
    assert est.stats == {"imu:no_speed": 1}


def _imports(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    out: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            out.append(node.module)
        elif isinstance(node, ast.Import):
            out.extend(a.name for a in node.names)
    return out


def test_the_core_never_imports_the_evaluation() -> None:
    core = Path(core_pkg.__file__).parent
    offenders = {
        p.name: m
        for p in core.rglob("*.py")
        for m in _imports(p)
        if m.startswith("tire_estimation.evaluation")
    }
    assert offenders == {}
    # the estimator the node runs loads no evaluation module
    code = (
        "import sys, tire_estimation.core.stiffness.estimator; "
        "print(any(m.startswith('tire_estimation.evaluation') for m in sys.modules))"
    )
    src = str(Path(core_pkg.__file__).parents[2])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([src, os.environ.get("PYTHONPATH", "")])}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env
    )
    assert out.stdout.strip() == "False"
