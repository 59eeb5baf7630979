"""EstimationPipeline: the ordered fast path computes what the reorder buffer computes."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pytest

from tire_estimation.core.pipeline import EstimationPipeline, PipelineConfig, RadiiOutput
from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.samples import Sample
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.evaluation.runner import RadiusRecorder
from tire_estimation.sim import simulate
from tire_estimation.sources import sim_samples


def _trace(ordered: bool, swap: bool = False) -> dict[str, np.ndarray]:
    sim = simulate("lane_change", seed=1, minutes=0.3)
    samples = list(sim_samples(sim, tire_forces=False))
    if swap:
        # one GNSS fix handed over after the wheel speeds that follow it: late, through the
        # buffer, processed after them (as a live node would)
        k = next(i for i, s in enumerate(samples) if s.KIND == "gnss_fix" and i > 2000)
        samples.insert(k + 3, samples.pop(k))
    rec = RadiusRecorder()
    p = EstimationPipeline(
        PipelineConfig(radius=RadiusEstimatorConfig(n_particles=50)), sim.vehicle, observers=[rec]
    )
    if ordered:
        p.push_ordered(samples)
    else:
        p.push_all(samples)
    return rec.finish(p).arrays()


def test_push_ordered_equals_push_on_a_merged_recording() -> None:
    a, b = _trace(ordered=True), _trace(ordered=False)
    assert a["t_ns"].size > 100
    for key in ("radius_error_m", "pose", "nis"):
        np.testing.assert_array_equal(a[key], b[key])


def test_an_out_of_order_sample_is_still_used() -> None:
    """A fix handed over after three later wheel samples: push_ordered cannot undo what it
    processed, so the fix goes through the buffer and is used late (not dropped); the run
    differs from the ordered one but keeps every fix."""
    late, ordered = _trace(ordered=True, swap=True), _trace(ordered=True)
    assert late["innov_t_ns"].size == ordered["innov_t_ns"].size
    assert np.all(np.isfinite(late["radius_error_m"]))
    assert not np.array_equal(late["radius_error_m"], ordered["radius_error_m"])


# ---------------------------------------------------------------- stamps that jump
HOUR_NS = 3600 * 1_000_000_000


def _faulted(samples: list[Sample], fault: str, at: int) -> list[Sample]:
    """The samples as a node receives them, with one clock fault from index ``at`` on."""
    out = list(samples)
    if fault == "future_outlier":
        out.insert(at, replace(out[at], t_ns=out[at].t_ns + 2 * HOUR_NS))
    elif fault == "past_outlier":
        out.insert(at, replace(out[at], t_ns=out[at].t_ns - 2 * HOUR_NS))
    elif fault in ("step_back", "step_ahead"):
        shift = -HOUR_NS if fault == "step_back" else HOUR_NS
        out[at:] = [replace(s, t_ns=s.t_ns + shift) for s in out[at:]]
    elif fault == "gnss_clock_ahead":
        out[at:] = [
            replace(s, t_ns=s.t_ns + 2 * HOUR_NS) if s.KIND == "gnss_fix" else s for s in out[at:]
        ]
    return out


@dataclass
class _Run:
    """What a run over the drive gave."""

    radii_m: np.ndarray
    n_radii: int = 0
    n_fixes_used: int = 0
    n_wheel: int = 0
    fix_used_after_wheel: list[int] = field(default_factory=list)
    n_late: int = 0
    dropped: dict[str, int] = field(default_factory=dict)

    def on_sample(self, pipeline: EstimationPipeline, sample: Sample, result: object) -> None:
        if sample.KIND == "wheel_speeds":
            self.n_wheel += 1
        elif sample.KIND == "gnss_fix" and result is not None:
            self.fix_used_after_wheel.append(self.n_wheel)

    def on_output(self, pipeline: EstimationPipeline, output: object) -> None:
        self.n_radii += type(output) is RadiiOutput


def _run(samples: list[Sample], vehicle: VehicleParams) -> _Run:
    run = _Run(np.zeros(0))
    p = EstimationPipeline(
        PipelineConfig(radius=RadiusEstimatorConfig(n_particles=50)), vehicle, observers=[run]
    )
    for s in samples:
        p.push(s)
    p.flush()
    assert p.radius is not None
    run.radii_m = np.asarray(p.radius.estimate().radius_error_m)
    run.n_late = sum(p.buffer.late.values())
    # fixes used while the drive went on (not held to the end of the recording)
    run.n_fixes_used = sum(n < run.n_wheel for n in run.fix_used_after_wheel)
    run.dropped = dict(p.clock.dropped)
    return run


@pytest.fixture(scope="module")
def clean_drive() -> tuple[list[Sample], VehicleParams, _Run]:
    sim = simulate("lane_change", seed=3, minutes=1.6, radius_offset_std_mm=3.0)
    samples = list(sim_samples(sim, tire_forces=False))
    return samples, sim.vehicle, _run(samples, sim.vehicle)


@pytest.mark.parametrize(
    "fault", ["future_outlier", "past_outlier", "step_back", "step_ahead", "gnss_clock_ahead"]
)
def test_estimation_goes_on_after_a_clock_fault(
    clean_drive: tuple[list[Sample], VehicleParams, _Run], fault: str
) -> None:
    """A fault 30 s into the drive; 60 s later the radii are within 1 mm of the clean run's,
    the radii kept coming, the fixes kept being used and the wheel speeds kept being put in
    stamp order (without the clock guard a clock stepped back stops the radius filter, a
    GNSS clock ahead leaves every later fix unused, and one sample two hours ahead makes
    every later sample late for the ordering)."""
    samples, vehicle, clean = clean_drive
    at = next(k for k, s in enumerate(samples) if s.t_ns - samples[0].t_ns > 30e9)
    run = _run(_faulted(samples, fault, at), vehicle)
    assert np.all(np.isfinite(run.radii_m))
    assert np.max(np.abs(run.radii_m - clean.radii_m)) < 1e-3
    assert run.n_radii >= 0.99 * clean.n_radii
    assert run.n_fixes_used >= 0.95 * clean.n_fixes_used
    assert run.n_late <= 5
    if fault.endswith("outlier"):
        assert run.dropped == {samples[at].KIND: 1}
        np.testing.assert_array_equal(run.radii_m, clean.radii_m)
