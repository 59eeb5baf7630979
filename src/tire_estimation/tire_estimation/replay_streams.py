"""The bag as the replay's report reads it: metadata, and the reference streams kept on disk.

The replay reads a bag in blocks (:mod:`tire_estimation.bag.stream`) and keeps, of the streams
the report compares against over the whole drive (GNSS fixes, truth and reference), the columns
it reads (:data:`KEPT`) in a :class:`~tire_estimation.spill.Spill`. :class:`ReportBag` stands
for :class:`~tire_estimation.bag.reader.BagData` in the report: its metadata as there, each such
stream a :class:`KeptStream` that gives the rows around a span of stamps
(:meth:`KeptStream.window`: what an interpolation at times in that span needs), rows by index,
or every k-th row (plots).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from tire_estimation.bag.reader import BagData
from tire_estimation.bag.stamp_merge import row_fields, take
from tire_estimation.spill import CHUNK_ROWS, PLOT_POINTS, Spill, plot_index

#: the streams the report reads whole-drive, and the row fields of each it reads (the others,
#: such as covariances, read as zeros)
KEPT: dict[str, tuple[str, ...]] = {
    "gnss": ("t_ns", "lat_deg", "lon_deg", "alt_m"),
    "truth_fix": ("t_ns", "lat_deg", "lon_deg", "alt_m"),
    "truth_odometry": ("t_ns", "linear_velocity_m_s", "angular_velocity_rad_s"),
    "reference_odometry": ("t_ns", "position_m", "linear_velocity_m_s", "angular_velocity_rad_s"),
    "truth_wheel_radii": ("t_ns", "values"),
    "truth_stiffness": ("t_ns", "values"),
    "reference_lateral": ("t_ns", "values"),
}
#: every this many rows a stamp is kept in memory to find rows by stamp
INDEX_STRIDE = 4096


class KeptStream:
    """One stream of the bag on disk, read back as its stream dataclass (e.g.
    :class:`~tire_estimation.sim.streams.GnssStream`) over a range of rows."""

    def __init__(self, spill: Spill, prefix: str, first: Any, fields: tuple[str, ...]) -> None:
        self._spill = spill
        self._prefix = prefix
        self._template = take(first, slice(0, 0))
        self._fields = fields
        self._sparse: list[np.ndarray] = []
        self.rows = 0

    def append(self, stream: Any) -> None:
        """Rows appended (later stamps than those already kept)."""
        for name in self._fields:
            self._spill.append(self._prefix + name, np.asarray(getattr(stream, name)))
        n0, m = self.rows, int(stream.t_ns.size)
        first = -(-n0 // INDEX_STRIDE) * INDEX_STRIDE
        self._sparse.append(np.asarray(stream.t_ns[first - n0 : m : INDEX_STRIDE]))
        self.rows += m

    def read(self, start: int = 0, stop: int | None = None) -> Any:
        """Rows ``start:stop`` (the fields not kept as zeros)."""
        stop = self.rows if stop is None else min(stop, self.rows)
        start = min(max(start, 0), stop)
        return self._stream(
            {name: self._spill.read(self._prefix + name, start, stop) for name in self._fields}
        )

    def _stream(self, kept: dict[str, np.ndarray]) -> Any:
        """The stream dataclass of the kept columns, the other row fields as zeros (read-only
        views of one row: no memory)."""
        rows = kept["t_ns"].shape[0]
        columns = dict(kept)
        for name in row_fields(self._template):
            if name not in kept:
                empty = getattr(self._template, name)
                zero = np.zeros(empty.shape[1:], dtype=empty.dtype)
                columns[name] = np.broadcast_to(zero, (rows, *empty.shape[1:]))
        return dataclasses.replace(self._template, **columns)

    def _position(self, t_ns: int, side: str) -> int:
        """``np.searchsorted(t_ns_of_all_rows, t_ns, side)``, reading a few rows."""
        sparse = np.concatenate(self._sparse) if self._sparse else np.zeros(0, np.int64)
        block = int(np.searchsorted(sparse, t_ns, side=side)) - 1
        if block < 0:
            return 0
        lo = block * INDEX_STRIDE
        t = self._spill.read(self._prefix + "t_ns", lo, lo + INDEX_STRIDE + 1)
        return lo + int(np.searchsorted(t, t_ns, side=side))

    def window(self, t0_ns: int, t1_ns: int) -> Any:
        """The rows with stamps in ``[t0_ns, t1_ns]`` and the row either side: what an
        interpolation (or a zero-order hold) at times in that span reads."""
        lo = max(self._position(int(t0_ns), "right") - 1, 0)
        hi = min(self._position(int(t1_ns), "left") + 1, self.rows)
        return self.read(lo, hi)

    def decimated(self, points: int = PLOT_POINTS) -> Any:
        """About ``points`` rows evenly spaced, the first and last included (all rows when
        there are no more)."""
        index = plot_index(self.rows, points)
        if index.size == self.rows:
            return self.read()
        parts: dict[str, list[np.ndarray]] = {name: [] for name in self._fields}
        for start in range(0, self.rows, CHUNK_ROWS):
            lo, hi = np.searchsorted(index, [start, start + CHUNK_ROWS])
            for name in self._fields:
                rows = self._spill.read(self._prefix + name, start, start + CHUNK_ROWS)
                parts[name].append(rows[index[lo:hi] - start])
        return self._stream({name: np.concatenate(p) for name, p in parts.items()})


class ReportBag:
    """:class:`BagData` for the report: its metadata (``meta``, with the counts of what reading
    dropped) and, for the streams of :data:`KEPT`, a :class:`KeptStream` (None: the bag has no
    rows of it)."""

    def __init__(self, meta: BagData, spill: Spill) -> None:
        self.meta = meta
        self._spill = spill
        self.kept: dict[str, KeptStream] = {}

    def add(self, block: BagData) -> None:
        """Keep the streams of :data:`KEPT` of a block (blocks in stamp order)."""
        for name, fields in KEPT.items():
            stream = getattr(block, name)
            if stream is None or stream.t_ns.size == 0:
                continue
            if name not in self.kept:
                prefix = self._spill.prefix(name)
                self.kept[name] = KeptStream(self._spill, prefix, stream, fields)
            self.kept[name].append(stream)

    def __getattr__(self, name: str) -> Any:
        if name in KEPT:
            return self.kept.get(name)
        return getattr(self.meta, name)

    @property
    def path(self) -> Path:
        """The bag's path."""
        return self.meta.path
