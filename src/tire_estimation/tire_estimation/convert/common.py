"""Helpers shared by the measured-data converters: loading, clocks, rotations, attribution."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from tire_estimation.bag.writer import TopicSeries, write_contract_bag
from tire_estimation.core.arrays import F64, I64
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import BagError

#: Standard gravity, m/s^2 (what a level accelerometer at rest reports on its up axis).
STANDARD_GRAVITY_M_S2 = 9.80665
#: Variance written for a velocity component that is not measured, m^2/s^2 (std 100 m/s).
UNMEASURED_VELOCITY_VARIANCE = 1.0e4
#: Variance written for a pose component that is not measured (m^2 or rad^2).
UNMEASURED_POSE_VARIANCE = 1.0e6
#: ``metadata.yaml`` custom-data keys written by the converters.
CUSTOM_SOURCE = "tire_estimation.source"
CUSTOM_CONVERSION = "tire_estimation.conversion"
CUSTOM_REFERENCE_ORIGIN = "tire_estimation.reference_origin_lla"
#: File written next to ``vehicle.yaml`` in a converted bag (choices, checks, origin).
CONVERSION_FILE = "conversion.yaml"
ATTRIBUTION_FILE = "ATTRIBUTION.md"


class ConvertError(BagError):
    """The input data of a converter is missing, malformed or inconsistent."""


def require_dir(path: Path, what: str) -> Path:
    """``path`` if it is a directory, else :class:`ConvertError` naming it."""
    if not path.is_dir():
        raise ConvertError(f"{what}: missing folder {path}")
    return path


def load_npy(path: Path, what: str) -> NDArray[Any]:
    """A NumPy array stored without extension (comma2k19 layout); ConvertError if absent/bad."""
    if not path.parent.is_dir():
        raise ConvertError(f"{what}: missing folder {path.parent}")
    if not path.is_file():
        raise ConvertError(f"{what}: missing file {path}")
    try:
        with path.open("rb") as fh:
            return np.load(fh, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise ConvertError(f"{what}: cannot read {path}: {exc}") from exc


def seconds_to_ns(t_s: NDArray[Any]) -> I64:
    """Seconds (float) to integer nanoseconds, rounded to the nearest ns."""
    return np.rint(np.asarray(t_s, dtype=np.float64) * 1e9).astype(np.int64)


def increasing_rows(t_ns: I64) -> NDArray[np.intp]:
    """Indices of the rows to keep so that the stamps are strictly increasing (first wins)."""
    if t_ns.size == 0:
        return np.zeros(0, dtype=np.intp)
    running = np.maximum.accumulate(t_ns)
    keep = np.ones(t_ns.size, dtype=bool)
    keep[1:] = t_ns[1:] > running[:-1]
    return np.flatnonzero(keep)


def diff_noise_std(x: F64) -> F64:
    """Noise std estimate of a densely sampled signal: std of first differences / sqrt(2)."""
    return np.std(np.diff(np.asarray(x, dtype=np.float64), axis=0), axis=0) / math.sqrt(2.0)


def matrices_to_quaternions_xyzw(rot: F64) -> F64:
    """Rotation matrices (M, 3, 3) to unit quaternions (M, 4) (x, y, z, w) with w >= 0."""
    quat = Rotation.from_matrix(rot).as_quat()
    quat *= np.where(quat[:, 3:4] < 0.0, -1.0, 1.0)
    return np.asarray(quat, dtype=np.float64)


def body_rates(t_s: F64, rot: F64) -> F64:
    """Angular velocity (M, 3) rad/s in body axes of a sampled attitude ``rot`` (M, 3, 3).

    ``rot[k]`` maps body vectors to the world frame. Central differences of the rotation
    (``log(R[k-1]^T R[k+1]) / (t[k+1] - t[k-1])``), one-sided at the ends.
    """
    n = len(t_s)
    if n < 2:
        return np.zeros((n, 3))
    lo = np.r_[0, np.arange(n - 2), n - 2]
    hi = np.r_[1, np.arange(2, n), n - 1]
    rel = np.einsum("nji,njk->nik", rot[lo], rot[hi])
    rotvec = Rotation.from_matrix(rel).as_rotvec()
    return np.asarray(rotvec / (t_s[hi] - t_s[lo])[:, None], dtype=np.float64)


def yaw_quaternions_xyzw(yaw_rad: F64) -> F64:
    """Quaternions (M, 4) (x, y, z, w) of rotations by ``yaw_rad`` about z."""
    half = 0.5 * np.asarray(yaw_rad, dtype=np.float64)
    zeros = np.zeros_like(half)
    return np.stack([zeros, zeros, np.sin(half), np.cos(half)], axis=1)


def attribution(body: str, command: str) -> str:
    """``ATTRIBUTION.md`` of a converted bag: ``body`` (the source, its licence, what was
    converted) and the ``command`` that made the bag."""
    return f"# Attribution\n\n{body}\n\nCommand:\n\n```\n{command}\n```\n"


def write_converted_bag(
    out_dir: Path | str,
    vehicle: VehicleParams,
    series: list[TopicSeries],
    info: Mapping[str, Any],
    *,
    source: str,
    conversion_keys: Sequence[str],
    attribution_md: str,
    vehicle_comment: str,
    source_files: Mapping[str, Path | None] | None = None,
    custom_data: Mapping[str, str] | None = None,
    overwrite: bool = False,
) -> Path:
    """Write a converted recording as a contract bag directory ``out_dir``; return its path.

    Next to the topics: ``conversion.yaml`` (``info``), ``ATTRIBUTION.md`` (``attribution_md``)
    and each of ``source_files`` (bag file name -> source path) that exists. Custom data:
    ``tire_estimation.source`` = ``source``, then ``custom_data``, then
    ``tire_estimation.conversion`` = the ``conversion_keys`` of ``info``.

    Raises:
        BagError: ``out_dir`` exists (without ``overwrite``) or cannot be written.
    """
    files: dict[str, str | bytes] = {
        CONVERSION_FILE: yaml.safe_dump(dict(info), sort_keys=False),
        ATTRIBUTION_FILE: attribution_md,
    }
    for name, path in (source_files or {}).items():
        if path is not None and path.is_file():
            files[name] = path.read_bytes()
    return write_contract_bag(
        out_dir,
        vehicle,
        series,
        vehicle_comment=vehicle_comment,
        custom_data={
            CUSTOM_SOURCE: source,
            **(custom_data or {}),
            CUSTOM_CONVERSION: yaml.safe_dump(
                {k: info[k] for k in conversion_keys}, sort_keys=False
            ),
        },
        extra_files=files,
        overwrite=overwrite,
    )
