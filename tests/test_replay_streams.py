"""KeptStream: a stream kept on disk block by block; the rows around a span of stamps
interpolate as the whole stream does."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tire_estimation import replay_streams
from tire_estimation.bag.stamp_merge import take
from tire_estimation.replay_streams import KeptStream, ReportBag
from tire_estimation.sim.streams import GnssStream
from tire_estimation.spill import Spill

N = 1000


def _fixes() -> GnssStream:
    rng = np.random.default_rng(3)
    t = 10_000 + np.cumsum(rng.integers(1, 50, N)).astype(np.int64)
    return GnssStream(t, 48 + rng.normal(0, 1e-3, N), 11 + rng.normal(0, 1e-3, N),
                      rng.normal(500, 1, N), np.ones((N, 3, 3)))  # fmt: skip


@pytest.fixture
def kept(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> KeptStream:
    monkeypatch.setattr(replay_streams, "INDEX_STRIDE", 16)
    fixes = _fixes()
    stream = KeptStream(Spill(tmp_path), "gnss.", fixes, ("t_ns", "lat_deg", "lon_deg"))
    for a, b in ((0, 5), (5, 300), (300, 301), (301, N)):
        stream.append(take(fixes, slice(a, b)))
    return stream


def test_rows_read_back_with_the_fields_not_kept_as_zeros(kept: KeptStream) -> None:
    fixes = _fixes()
    assert kept.rows == N
    part = kept.read(100, 140)
    np.testing.assert_array_equal(part.t_ns, fixes.t_ns[100:140])
    np.testing.assert_array_equal(part.lat_deg, fixes.lat_deg[100:140])
    np.testing.assert_array_equal(part.alt_m, np.zeros(40))  # not kept
    assert part.position_covariance_m2.shape == (40, 3, 3)


@pytest.mark.parametrize("span", [(0, 5), (37, 38), (120, 700), (999, 999), (-50, 2000)])
def test_a_window_interpolates_as_the_whole_stream(
    kept: KeptStream, span: tuple[int, int]
) -> None:
    fixes = _fixes()
    t = fixes.t_ns
    lo, hi = np.clip(span, 0, N - 1)
    # query times between the rows (and beyond both ends)
    before, after = (100 if span[0] < 0 else 0), (100 if span[1] >= N else 0)
    query = np.linspace(t[lo] - before, t[hi] + after, 57)
    w = kept.window(int(query[0]), int(query[-1]))
    assert w.t_ns.size <= hi - lo + 3
    np.testing.assert_array_equal(
        np.interp(query, w.t_ns, w.lat_deg), np.interp(query, t, fixes.lat_deg)
    )


def test_decimated_rows_are_evenly_spaced_with_both_ends(kept: KeptStream) -> None:
    fixes = _fixes()
    few = kept.decimated(100)
    assert few.t_ns[0] == fixes.t_ns[0] and few.t_ns[-1] == fixes.t_ns[-1]
    assert 90 <= few.t_ns.size <= 102
    np.testing.assert_array_equal(kept.decimated(5000).t_ns, fixes.t_ns)


def test_the_report_bag_keeps_the_reference_streams_of_each_block(tmp_path: Path) -> None:
    from tire_estimation.bag.reader import BagData
    from tire_estimation.core.vehicle import VehicleParams

    meta = BagData(Path("b"), VehicleParams(), 0, 1.0, {})
    bag = ReportBag(meta, Spill(tmp_path))
    fixes = _fixes()
    for a, b in ((0, 400), (400, N)):
        part = take(fixes, slice(a, b))
        bag.add(BagData(Path("b"), VehicleParams(), 0, 1.0, {}, truth_fix=part))
    assert bag.truth_fix is not None and bag.truth_fix.rows == N
    assert bag.gnss is None and bag.vehicle is meta.vehicle and bag.path == Path("b")
    np.testing.assert_array_equal(bag.truth_fix.read().alt_m, fixes.alt_m)
