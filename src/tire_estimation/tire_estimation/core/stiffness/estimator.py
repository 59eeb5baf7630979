"""Tyre-stiffness estimator: Algorithm 1 (Berntorp & Di Cairano, IEEE TCST 2018) behind the
front-end.

:class:`StiffnessEstimator` drives :class:`~tire_estimation.core.stiffness.mpf.StiffnessMpf`
(through :class:`MpfFilter`) from the asynchronous sensor callbacks of
:class:`~tire_estimation.core.stiffness.frontend.StiffnessFrontEnd`: the input checks, the
speed and the activation are the front-end's. Added here, for Algorithm 1 only: the
point-mass filter of :mod:`~.grid` learning first and handing its posterior over
(``first_learning`` = ``grid``), the predictive density of the measurements, and the learned
statistics as a state to save and restore.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from tire_estimation.core import niw
from tire_estimation.core import state_checks as checks
from tire_estimation.core.arrays import F64
from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.core.stiffness.filter import FilterEstimate, Measurement, StiffnessFilter
from tire_estimation.core.stiffness.frontend import (
    StiffnessEstimate,
    StiffnessFrontEnd,
    TraceRow,
    sideslip,
)
from tire_estimation.core.stiffness.grid import GridConfig, GridEkf, posterior
from tire_estimation.core.stiffness.model import MAX_STIFFNESS_FRACTION, MIN_STIFFNESS_FRACTION
from tire_estimation.core.stiffness.mpf import StiffnessMpf
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import InputError

STATE_DICT_VERSION = 1
#: ``first_learning`` = ``grid``: the hand-over happens, and the grid stays published after it,
#: only while the grid's mean normalized innovation squared (``GridEkf.nis_mean``, 3
#: measurements: about 3 when its model fits) is at most this. 2.9-4.9 on the simulated sine
#: drives, 68 on the Revs 250 LM run, whose posterior would be confident and wrong.
GRID_MAX_NIS = 10.0


class MpfFilter(StiffnessFilter):
    """Algorithm 1 (:class:`StiffnessMpf`) as the filter of the front-end.

    Args:
        mpf: the marginalized particle filter.
    """

    def __init__(self, mpf: StiffnessMpf) -> None:
        self.mpf = mpf

    @property  # type: ignore[override]
    def initialized(self) -> bool:
        """The MPF has been initialized (cleared by the front-end after a gap)."""
        return self.mpf.initialized

    @initialized.setter
    def initialized(self, value: bool) -> None:
        self.mpf.initialized = value

    def initialize(self, x0: F64, x0_std: F64) -> None:
        """Particles around ``x0`` with std ``x0_std``, the prior statistics."""
        self.mpf.initialize(x0, x0_std)

    def predict(self, dt_s: float, learn: bool, learn_cx: bool) -> None:
        """Time part of Algorithm 1 (eq. 9, 20)."""
        self.mpf.predict(dt_s, learn, learn_cx)

    def update(self, meas: Measurement, learn: bool, learn_cx: bool) -> None:
        """Measurement part of Algorithm 1; a measured vX goes in as the MPF's speed input."""
        vx_m_s = meas.speed_m_s if meas.vx_measured else None
        self.mpf.update(meas.y, meas.delta_rad, meas.wheel_speed_m_s, learn, vx_m_s, learn_cx)

    def estimate(self) -> FilterEstimate:
        """Estimates (27) of the stiffness and (42) of the state, the mean IMU bias."""
        # the fields of StiffnessMpf.estimate, without building it
        out = self.mpf.estimate_vector()
        return FilterEstimate(
            stiffness=out[0:3],
            stiffness_std=out[3:6],
            state=out[9:12],
            state_cov=out[12:21].reshape(3, 3),
            n_eff=float(self.mpf.n_eff),
            bias=out[21:24],
        )


class StiffnessEstimator(StiffnessFrontEnd[MpfFilter]):
    """Algorithm 1 behind the front-end.

    Args:
        config: :class:`StiffnessEstimatorConfig`.
        vehicle: :class:`VehicleParams` (geometry, nominal stiffness, drive).
        rng: random generator of every draw.
    """

    config: StiffnessEstimatorConfig

    def __init__(
        self,
        config: StiffnessEstimatorConfig,
        vehicle: VehicleParams,
        rng: np.random.Generator,
    ) -> None:
        #: times the grid handed its posterior to Algorithm 1 (``first_learning`` = ``grid``)
        self.handover_count = 0
        #: times the grid was dropped by its NIS gate (mean NIS above :data:`GRID_MAX_NIS`:
        #: its model does not fit the data, or no longer), before or after the hand-over
        self.grid_rejection_count = 0
        super().__init__(config, vehicle, rng)

    def make_filter(self) -> MpfFilter:
        """A fresh :class:`StiffnessMpf`."""
        return MpfFilter(StiffnessMpf(self.config, self.params, self.rng))

    @property
    def mpf(self) -> StiffnessMpf:
        """Algorithm 1's filter."""
        return self.filter.mpf

    @mpf.setter
    def mpf(self, mpf: StiffnessMpf) -> None:
        self.filter.mpf = mpf

    def reset(self) -> None:
        """Forget everything learned and all inputs."""
        super().reset()
        # first_learning = grid: the point-mass filter that learns first (None once dropped)
        self._grid: GridEkf | None = None
        self._handed_over = False
        if self.config.first_learning == "grid":
            self._grid = GridEkf(GridConfig.sharing(self.config), self.params)

    # ------------------------------------------------------------------ front-end hooks
    def _on_initialize(self, x0: F64, x0_std: F64) -> None:
        if self._grid is not None and self._handed_over:
            # Algorithm 1 keeps its learned statistics: a grid from the prior must not be
            # published over them
            self._grid = None
        elif self._grid is not None:
            self._grid.initialize(x0, x0_std)

    def _after_step(self, t_ns: int, dt_s: float | None, meas: Measurement) -> None:
        if self._grid is not None:
            self._grid_step(dt_s, meas)

    # ------------------------------------------------------------------ first_learning = grid
    def _grid_step(self, dt: float | None, meas: Measurement) -> None:
        """``first_learning`` = ``grid``: one step of the grid with the MPF's inputs and learning
        flags. Once it has learned ``grid_handover_s``: dropped whenever its mean NIS is above
        :data:`GRID_MAX_NIS`; else the hand-over, and the grid goes on (published) until it
        has learned ``grid_publish_s``."""
        grid = self._grid
        assert grid is not None
        if dt is not None:
            grid.predict(dt, self._active, self._cx_active)
        grid.update(meas, self._active, self._cx_active)
        c = self.config
        if grid.learned_s < c.grid_handover_s:
            return
        if grid.nis_mean > GRID_MAX_NIS:
            # the grid's model does not fit these data (or no longer: the stiffness changed):
            # no hand-over, or no more publishing; Algorithm 1 goes on
            self._grid = None
            self.grid_rejection_count += 1
        elif not self._handed_over:
            self._hand_over()
        elif grid.learned_s >= c.grid_publish_s:
            self._grid = None

    def _hand_over(self) -> None:
        """The grid's posterior of ``(Cy_f, Cy_r)`` becomes Algorithm 1's NiW statistics
        (:func:`niw.stats_from_moments`, as a restored state): the grid's mean, and ``gamma`` such
        that ``gamma E[Sigma]`` has the trace of the grid's covariance over the two cornering
        stiffnesses (the NiW shares one ``gamma``: Cx's prior uncertainty must not set it); Cx,
        the expected noise covariance and the dof as the MPF has them."""
        assert self._grid is not None
        m, cov = posterior(self._grid)
        est = niw.mmse(self.mpf.stats, self.mpf.weights)
        mean = est.mean.copy()
        mean[1:] = m
        gamma = np.trace(cov) / max(float(np.trace(est.noise_cov[1:, 1:])), 1e-300)
        self.mpf.stats = niw.stats_from_moments(
            self.mpf.n, mean, gamma * est.noise_cov, est.noise_cov, est.dof
        )
        self._handed_over = True
        if self._grid.learned_s >= self.config.grid_publish_s:
            self._grid = None
        self.handover_count += 1

    # ------------------------------------------------------------------ outputs
    def estimate(self) -> StiffnessEstimate:
        """Current estimate (see :class:`StiffnessEstimate`)."""
        e = self.filter.estimate()
        grid = self._published_grid()
        if grid is not None:
            e = dataclasses.replace(
                e,
                stiffness=np.concatenate([e.stiffness[:1], grid.stiffness[1:]]),
                stiffness_std=np.concatenate([e.stiffness_std[:1], grid.stiffness_std[1:]]),
            )
        return self._published(e, mean_log_predictive=self._mean_log_predictive())

    def trace_row(self) -> TraceRow:
        """What a recorder keeps of :meth:`estimate` at every IMU sample, without building the
        estimate: the same values."""
        out = self.mpf.estimate_vector()  # a new vector at every call: its slices are ours
        stiffness, stiffness_std = out[0:3], out[3:6]
        grid = self._published_grid()
        if grid is not None:
            stiffness[1:], stiffness_std[1:] = grid.stiffness[1:], grid.stiffness_std[1:]
        vx, vy, r = out[9:12].tolist()
        return TraceRow(
            vx, vy, r, sideslip(vx, vy), stiffness, stiffness_std, self._active, float(out[23]),
            self._mean_log_predictive(),
        )  # fmt: skip

    def _published_grid(self) -> FilterEstimate | None:
        """``first_learning`` = ``grid``: the grid's estimate, whose cornering stiffness is
        published until the hand-over, or until ``grid_publish_s``; else None."""
        if self._grid is not None and self._grid.learned_s > 0.0:
            return self._grid.estimate()
        return None

    def _mean_log_predictive(self) -> float:
        return self.mpf.log_evidence / max(self.mpf.evidence_steps, 1)

    def state_dict(self) -> dict[str, Any]:
        """Learned stiffness statistics (JSON-serializable)."""
        est = niw.mmse(self.mpf.stats, self.mpf.weights)
        return {
            "version": STATE_DICT_VERSION,
            "vehicle": self.vehicle.name,
            "names": list(self.params.names),
            "nominal": self.mpf.nominal.tolist(),
            "mean": est.mean.tolist(),
            "mean_cov": est.mean_cov.tolist(),
            "noise_cov": est.noise_cov.tolist(),
            "dof": float(est.dof),
        }

    def load_state_dict(self, d: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict` output; raises InputError (kind ``state``) naming the
        value when it belongs to another vehicle or nominal stiffness or is not plausible: the
        mean within the projection bounds (``MIN_STIFFNESS_FRACTION`` to
        ``MAX_STIFFNESS_FRACTION`` of nominal), the covariances positive definite with
        standard deviations up to the width of those bounds (or the configured prior std, when
        larger), the dof finite within (4, 1e9]. Nothing changes unless the whole state is
        valid."""
        k = "state"
        checks.require_keys(
            k,
            "stiffness state",
            d,
            ("version", "vehicle", "nominal", "mean", "mean_cov", "noise_cov", "dof"),
            ("names",),
        )
        checks.choice(k, "stiffness state version", d["version"], STATE_DICT_VERSION)
        if d["vehicle"] != self.vehicle.name:
            raise InputError(k, f"state of vehicle {checks.shown(d['vehicle'])}")
        if "names" in d:
            checks.choice(k, "names", d["names"], list(self.params.names))
        # the learned part is relative to the nominal stiffness (eq. 7): a state learned
        # with other nominal values would be restored as the wrong stiffness
        nominal = checks.vector(k, "nominal", d["nominal"], 3)
        if not np.allclose(nominal, self.mpf.nominal, rtol=1e-6, atol=0.0):
            raise InputError(
                k,
                f"state learned with nominal stiffness {nominal.tolist()}, now "
                f"{self.mpf.nominal.tolist()}",
            )
        mean = checks.vector(k, "mean", d["mean"], 3)
        lower, upper = self.mpf.lower, self.mpf.upper
        if np.any(mean < lower) or np.any(mean > upper):
            raise InputError(
                k,
                f"mean={mean.tolist()} is outside the stiffness bounds "
                f"[{lower.tolist()}, {upper.tolist()}] (relative to nominal)",
            )
        c = self.config
        widest = max(
            MAX_STIFFNESS_FRACTION - MIN_STIFFNESS_FRACTION,
            c.initial_stiffness_std_fraction,
            c.stiffness_noise_std_fraction,
        )
        stds = (
            checks.MIN_STD_FRACTION * float(np.min(self.mpf.nominal)),
            widest * float(np.max(self.mpf.nominal)),
        )
        mean_cov = checks.covariance(k, "mean_cov", d["mean_cov"], 3, *stds)
        noise_cov = checks.covariance(k, "noise_cov", d["noise_cov"], 3, *stds)
        dof = checks.dof(k, "dof", d["dof"], 3)
        stats = niw.stats_from_moments(self.mpf.n, mean, mean_cov, noise_cov, dof)
        if not all(np.all(np.isfinite(a)) for a in (stats.mean, stats.scale, stats.gamma)):
            raise InputError(k, "non-finite statistics")
        self.mpf.stats = stats
        # restored statistics are learned, not a prior to learn on a grid
        self._grid = None


__all__ = ["GRID_MAX_NIS", "MpfFilter", "StiffnessEstimate", "StiffnessEstimator"]
