"""Whole-drive records kept on disk: append-only columns in a directory.

The streaming replay records what the report needs over the whole drive (the estimators'
traces, the truth and reference streams) block by block; :func:`drain` moves the rows a
recorder holds in lists to a :class:`Spill` and empties the lists, and :class:`Spilled` reads
them back: a whole column when a computation needs it (the traces at the GNSS rate), a range
of rows at a time (:func:`row_chunks`, the 100-Hz traces), or every k-th row (:func:`decimated`,
plots). Columns are read into memory (``np.fromfile``), not memory-mapped, so that a
computation's pages leave the process when it is done.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: rows of a column read at a time by :func:`row_chunks`
CHUNK_ROWS = 1 << 16
#: points of a series a plot shows at most (:func:`decimated`)
PLOT_POINTS = 20_000


@dataclass
class _Column:
    path: Path
    dtype: np.dtype[Any]
    shape: tuple[int, ...]
    rows: int = 0


class Spill:
    """Append-only columns (a fixed dtype and row shape each) in the directory ``root``.

    Strings are kept as integer codes with their vocabulary (:meth:`append_strings`).
    """

    def __init__(self, root: Path) -> None:
        self.root = Path(root)
        self._columns: dict[str, _Column] = {}
        self._vocab: dict[str, dict[str, int]] = {}
        self._prefixes = 0

    def prefix(self, what: str) -> str:
        """A new name prefix for the columns of one record."""
        self._prefixes += 1
        return f"{what}{self._prefixes}."

    def __contains__(self, name: str) -> bool:
        return name in self._columns

    def rows(self, name: str) -> int:
        """Rows of a column (0 when it has none)."""
        col = self._columns.get(name)
        return 0 if col is None else col.rows

    def append(self, name: str, values: NDArray[Any]) -> None:
        """Rows appended to column ``name`` (the first call sets its dtype and row shape)."""
        values = np.ascontiguousarray(values)
        if values.shape[0] == 0:
            return
        col = self._columns.get(name)
        if col is None:
            path = self.root / f"{len(self._columns)}.bin"
            col = self._columns[name] = _Column(path, values.dtype, values.shape[1:])
        if values.dtype != col.dtype or values.shape[1:] != col.shape:
            raise ValueError(
                f"spill column {name}: rows {values.dtype} {values.shape[1:]}, "
                f"expected {col.dtype} {col.shape}"
            )
        with col.path.open("ab") as f:
            values.tofile(f)
        col.rows += values.shape[0]

    def append_strings(self, name: str, values: Sequence[str]) -> None:
        """Strings appended to column ``name`` (as codes)."""
        vocab = self._vocab.setdefault(name, {})
        codes = [vocab.setdefault(v, len(vocab)) for v in values]
        self.append(name, np.asarray(codes, dtype=np.int32))

    def read(self, name: str, start: int = 0, stop: int | None = None) -> NDArray[Any]:
        """Rows ``start:stop`` of a column, in memory."""
        col = self._columns[name]
        stop = col.rows if stop is None else min(stop, col.rows)
        start = min(max(start, 0), stop)
        per_row = int(np.prod(col.shape, dtype=np.int64))
        values = np.fromfile(
            col.path,
            dtype=col.dtype,
            count=(stop - start) * per_row,
            offset=start * per_row * col.dtype.itemsize,
        )
        return values.reshape((stop - start, *col.shape))

    def holds_strings(self, name: str) -> bool:
        """Whether column ``name`` holds strings (:meth:`append_strings`)."""
        return name in self._vocab

    def read_strings(self, name: str) -> list[str]:
        """A column of strings, whole."""
        words = {code: word for word, code in self._vocab[name].items()}
        return [words[int(c)] for c in self.read(name)]


def drain(obj: Any, spill: Spill, prefix: str, keep: Iterable[str] = ()) -> None:
    """Move the rows ``obj`` holds in list attributes (a trace, a recorder) to columns
    ``prefix + attribute`` of ``spill`` and empty the lists; lists of strings are kept as codes.
    ``keep``: list attributes left in memory (a few items, such as alarms)."""
    kept = set(keep)
    for name, values in vars(obj).items():
        if not isinstance(values, list) or name in kept or not values:
            continue
        if isinstance(values[0], str):
            spill.append_strings(prefix + name, values)
        else:
            spill.append(prefix + name, np.asarray(values))
        values.clear()


class Spilled:
    """Read-only view of an object :func:`drain` emptied: its list attributes read back whole
    from the spill (strings as a list), ``arrays()`` (when the object has it) reads each array
    when asked, and everything else is the object's own (setting an attribute sets it there)."""

    def __init__(self, obj: Any, spill: Spill, prefix: str) -> None:
        object.__setattr__(self, "_obj", obj)
        object.__setattr__(self, "_spill", spill)
        object.__setattr__(self, "_prefix", prefix)

    def __getattr__(self, name: str) -> Any:
        spill: Spill = object.__getattribute__(self, "_spill")
        column = object.__getattribute__(self, "_prefix") + name
        if column in spill:
            if spill.holds_strings(column):
                return spill.read_strings(column)
            return spill.read(column)
        return getattr(object.__getattribute__(self, "_obj"), name)

    def __setattr__(self, name: str, value: Any) -> None:
        setattr(object.__getattribute__(self, "_obj"), name, value)

    def arrays(self) -> Mapping[str, NDArray[Any]]:
        """The object's ``arrays()``, each read from the spill when asked."""
        return _LazyArrays(self)

    def rows(self, key: str) -> int:
        """Rows recorded under ``key``."""
        return self._spill.rows(self._prefix + key)

    def read(self, key: str, start: int = 0, stop: int | None = None) -> NDArray[Any]:
        """Rows ``start:stop`` of ``key`` (the object's own, empty, array when none)."""
        column = self._prefix + key
        if column in self._spill:
            return self._spill.read(column, start, stop)
        return np.asarray(self._obj.arrays()[key])[start:stop]


class _LazyArrays(Mapping[str, NDArray[Any]]):
    def __init__(self, view: Spilled) -> None:
        self._view = view
        self._keys = tuple(view._obj.arrays())

    def __getitem__(self, key: str) -> NDArray[Any]:
        if key not in self._keys:
            raise KeyError(key)
        return self._view.read(key)

    def __iter__(self) -> Iterator[str]:
        return iter(self._keys)

    def __len__(self) -> int:
        return len(self._keys)


def rows_of(trace: Any, key: str) -> int:
    """Rows of ``trace.arrays()[key]`` (a :class:`Spilled` trace: without reading them)."""
    if isinstance(trace, Spilled):
        return trace.rows(key)
    return len(trace.arrays()[key])


def row_chunks(
    trace: Any, keys: Sequence[str], size: int | None = None, start: int = 0
) -> Iterator[dict[str, NDArray[Any]]]:
    """``trace.arrays()`` restricted to ``keys`` (columns of equal length) from row ``start``
    on, ``size`` (default :data:`CHUNK_ROWS`) rows at a time; a :class:`Spilled` trace is read
    a chunk at a time."""
    size = CHUNK_ROWS if size is None else size
    n = rows_of(trace, keys[0])
    if isinstance(trace, Spilled):
        for a in range(start, n, size):
            yield {k: trace.read(k, a, a + size) for k in keys}
        return
    arr = trace.arrays()
    for a in range(start, n, size):
        yield {k: np.asarray(arr[k])[a : a + size] for k in keys}


def plot_index(n: int, points: int = PLOT_POINTS) -> NDArray[np.intp]:
    """Indices of at most about ``points`` rows of ``n``, evenly spaced, the last included."""
    step = max(1, -(-n // points))
    index = np.arange(0, n, step)
    if n and index[-1] != n - 1:
        index = np.append(index, n - 1)
    return index


def decimated(
    trace: Any, keys: Sequence[str], points: int = PLOT_POINTS
) -> dict[str, NDArray[Any]]:
    """The rows :func:`plot_index` picks of ``keys`` (columns of equal length), read chunk by
    chunk (all rows when there are no more than ``points``)."""
    n = rows_of(trace, keys[0])
    index = plot_index(n, points)
    parts: dict[str, list[NDArray[Any]]] = {k: [] for k in keys}
    start = 0
    for chunk in row_chunks(trace, keys):
        m = len(chunk[keys[0]])
        lo, hi = np.searchsorted(index, [start, start + m])
        for k in keys:
            parts[k].append(chunk[k][index[lo:hi] - start])
        start += m
    return {
        k: np.concatenate(v) if v else np.asarray(trace.arrays()[k])[:0] for k, v in parts.items()
    }
