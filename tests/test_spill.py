"""spill: a trace drained block by block reads back as the trace recorded whole."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tire_estimation.evaluation.runner import RadiusTrace
from tire_estimation.spill import (
    Spill,
    Spilled,
    decimated,
    drain,
    plot_index,
    row_chunks,
    rows_of,
)


def _record(trace: RadiusTrace, k: int) -> None:
    trace.t_ns.append(1_000 + k)
    trace.radius_error_m.append(np.array([k, -k], dtype=float))
    trace.active.append(np.array([k % 2 == 0, True]))
    trace.reason.append("learning" if k % 3 else "low speed")
    if k % 2:
        trace.innov_t_ns.append(1_000 + k)
        trace.nis.append(0.5 * k)


def _recorded(n: int) -> RadiusTrace:
    trace = RadiusTrace(wheel_names=("wheel_rl", "wheel_rr"))
    for k in range(n):
        _record(trace, k)
    return trace


def test_a_drained_trace_reads_back_as_the_whole_trace(tmp_path: Path) -> None:
    spill = Spill(tmp_path)
    trace = RadiusTrace(wheel_names=("wheel_rl", "wheel_rr"))
    prefix = spill.prefix("radius")
    for block in (range(0, 7), range(7, 8), range(8, 8), range(8, 20)):
        for k in block:
            _record(trace, k)
        drain(trace, spill, prefix)
        assert trace.t_ns == [] and trace.reason == []
    view = Spilled(trace, spill, prefix)
    whole = _recorded(20)
    expected, got = whole.arrays(), view.arrays()
    assert list(got) == list(expected)
    for key in expected:
        np.testing.assert_array_equal(got[key], expected[key], err_msg=key)
        assert got[key].dtype == expected[key].dtype or expected[key].size == 0, key
    assert view.reason == whole.reason
    np.testing.assert_array_equal(view.innov_t_ns, whole.innov_t_ns)
    assert view.wheel_names == ("wheel_rl", "wheel_rr")
    view.dropped = {"gnss_fix:nan": 1}  # set on the trace itself
    assert trace.dropped == {"gnss_fix:nan": 1}
    assert rows_of(view, "t_ns") == 20 and rows_of(view, "innov_t_ns") == 10


def test_chunks_and_decimation_of_a_spilled_and_an_in_memory_trace(tmp_path: Path) -> None:
    spill = Spill(tmp_path)
    trace = _recorded(50)
    whole = _recorded(50)
    prefix = spill.prefix("radius")
    drain(trace, spill, prefix)
    view = Spilled(trace, spill, prefix)
    for source in (view, whole):
        chunks = list(row_chunks(source, ("t_ns", "radius_error_m"), size=7))
        assert [len(c["t_ns"]) for c in chunks] == [7] * 7 + [1]
        t = np.concatenate([c["t_ns"] for c in chunks])
        np.testing.assert_array_equal(t, whole.arrays()["t_ns"])
        last = next(row_chunks(source, ("radius_error_m",), size=1, start=49))
        np.testing.assert_array_equal(last["radius_error_m"], [[49.0, -49.0]])
        few = decimated(source, ("t_ns", "radius_error_m"), points=10)
        np.testing.assert_array_equal(few["t_ns"], 1_000 + plot_index(50, 10))
        assert few["t_ns"][-1] == 1_049 and few["radius_error_m"].shape == (11, 2)


def test_plot_index_keeps_every_row_when_few_and_the_last_always() -> None:
    np.testing.assert_array_equal(plot_index(5, 10), np.arange(5))
    index = plot_index(1001, 100)
    assert index[0] == 0 and index[-1] == 1000 and index.size <= 101 + 1
    assert plot_index(0).size == 0


def test_a_column_keeps_its_dtype_and_row_shape(tmp_path: Path) -> None:
    spill = Spill(tmp_path)
    spill.append("x", np.zeros((3, 2)))
    spill.append("x", np.ones((2, 2)))
    np.testing.assert_array_equal(spill.read("x", 2, 4), [[0.0, 0.0], [1.0, 1.0]])
    with pytest.raises(ValueError, match="spill column x"):
        spill.append("x", np.zeros((1, 3)))
