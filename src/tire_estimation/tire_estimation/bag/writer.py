"""Write contract bags: a simulated drive (:func:`write_sim_bag`) or any topic series
(:func:`write_contract_bag`, used by the measured-data converters).

The bag is a rosbag2 directory (format version 9, MCAP storage, zstd chunk compression by
default) holding the input, truth topics of contract v1, plus ``vehicle.yaml`` and
``sim_config.yaml`` inside the bag directory. Header stamps are the measurement times and every
message's log time equals its header stamp. The bag is written to a hidden temporary directory
and renamed into place only when complete.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import uuid
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

from tire_estimation.bag import messages as mb
from tire_estimation.bag import topics as tp
from tire_estimation.bag.cdr import Encoder, iter_rows
from tire_estimation.bag.typestore import get_typestore
from tire_estimation.core.vehicle import VehicleParams, dump_vehicle_yaml
from tire_estimation.core.wheels import WHEELS
from tire_estimation.errors import BagError
from tire_estimation.sim.streams import ImuStream, SimResult

_NS_PER_S = 1_000_000_000

#: Truth topics written at a reduced rate: a message at least every ``TRUTH_PERIOD_NS`` and
#: whenever any value moved by more than its tolerance since the last message (so a receiver
#: holding the last value stays within the tolerance of the truth).
TRUTH_PERIOD_NS = _NS_PER_S
TRUTH_RADIUS_TOL_M = 1e-5
TRUTH_PRESSURE_TOL_PA = 50.0
TRUTH_STIFFNESS_REL_TOL = 1e-3

VEHICLE_FILE = "vehicle.yaml"
SIM_CONFIG_FILE = "sim_config.yaml"
#: Keys of the bag's ``metadata.yaml`` custom data.
CUSTOM_VEHICLE = "tire_estimation.vehicle"
CUSTOM_SCENARIO = "tire_estimation.scenario"
CUSTOM_SEED = "tire_estimation.seed"
CUSTOM_EVENTS = "tire_estimation.events"
CUSTOM_ORIGIN = "tire_estimation.origin_lla"
CUSTOM_CONTRACT = "tire_estimation.contract"


@dataclass(frozen=True)
class TopicSeries:
    """All messages of one topic, in two equivalent forms.

    ``t_ns``: header stamps (= log times), ns. ``template``: the first message (a ``rosbags``
    object). ``values``: numeric fields that vary between messages, by CDR path (see
    :mod:`tire_estimation.bag.cdr`), first axis = message; the header stamp is added by the
    encoder. ``build(i)``: the i-th message object, built independently with
    :mod:`tire_estimation.bag.messages` (generic path, and for publishing over DDS).
    """

    topic: str
    msgtype: str
    t_ns: NDArray[np.int64]
    template: Any
    values: dict[str, NDArray[Any]]
    build: Callable[[int], Any]

    def serialize(self, *, fast: bool = True) -> list[bytes] | list[memoryview]:
        """CDR bytes of every message; ``fast`` stamps values into the template in bulk."""
        store = get_typestore()
        if not fast:
            return [
                bytes(store.serialize_cdr(self.build(i), self.msgtype))
                for i in range(len(self.t_ns))
            ]
        sec, nanosec = np.divmod(self.t_ns, _NS_PER_S)
        values = {"header.stamp.sec": sec, "header.stamp.nanosec": nanosec, **self.values}
        rows = Encoder(store, self.msgtype, self.template).encode(len(self.t_ns), values)
        return list(iter_rows(rows))


def reduced_rate_rows(
    t_ns: NDArray[np.int64], values: NDArray[np.float64], tol: NDArray[np.float64] | float
) -> NDArray[np.int64]:
    """Rows to publish of a slowly varying truth signal.

    Keeps row 0, then a row whenever :data:`TRUTH_PERIOD_NS` passed since the last kept row or
    any column moved by more than ``tol`` (same unit as ``values``) from it, and the last row.
    """
    count = len(t_ns)
    if count == 0:
        return np.zeros(0, dtype=np.int64)
    tols = np.broadcast_to(np.asarray(tol, dtype=np.float64), values.shape[1:]).tolist()
    rows = values.tolist()
    times = t_ns.tolist()
    keep = [0]
    last, last_t = rows[0], times[0]
    for i in range(1, count):
        row = rows[i]
        if times[i] - last_t >= TRUTH_PERIOD_NS or any(
            not abs(a - b) <= tl for a, b, tl in zip(row, last, tols, strict=True)
        ):
            keep.append(i)
            last, last_t = row, times[i]
    if keep[-1] != count - 1:
        keep.append(count - 1)
    return np.asarray(keep, dtype=np.int64)


def joint_series(
    topic: str,
    t_ns: NDArray[np.int64],
    names: tuple[str, ...],
    field: str,
    data: NDArray[np.float64],
) -> TopicSeries:
    """JointState series whose ``field`` (position, velocity or effort) is ``data`` (M, names)."""
    data = np.ascontiguousarray(data, dtype=np.float64).reshape(len(t_ns), len(names))

    def build(i: int) -> Any:
        return mb.joint_state(int(t_ns[i]), names, **{field: data[i]})

    return TopicSeries(topic, tp.JOINT_STATE, t_ns, build(0), {field: data}, build)


def fix_series(
    topic: str,
    t_ns: NDArray[np.int64],
    lat: NDArray[np.float64],
    lon: NDArray[np.float64],
    alt: NDArray[np.float64],
    cov: NDArray[np.float64],
    frame_id: str,
    *,
    covariance_type: int = mb.COVARIANCE_TYPE_KNOWN,
) -> TopicSeries:
    """NavSatFix series (deg, deg, m) with ENU covariance ``cov`` (M, 3, 3) m^2 and one
    ``position_covariance_type`` for every message."""
    cov9 = np.ascontiguousarray(cov, dtype=np.float64).reshape(len(t_ns), 9)

    def build(i: int) -> Any:
        return mb.nav_sat_fix(
            int(t_ns[i]),
            lat[i],
            lon[i],
            alt[i],
            cov9[i],
            frame_id=frame_id,
            covariance_type=covariance_type,
        )

    values = {
        "latitude": lat,
        "longitude": lon,
        "altitude": alt,
        "position_covariance": cov9,
    }
    return TopicSeries(topic, tp.NAV_SAT_FIX, t_ns, build(0), values, build)


def imu_series(imu: ImuStream, topic: str = tp.IMU_DATA) -> TopicSeries:
    """Imu series of ``imu`` (base_link axes, diagonal covariances from the noise std)."""

    def build(i: int) -> Any:
        return mb.imu(
            int(imu.t_ns[i]),
            imu.angular_velocity_rad_s[i],
            imu.linear_acceleration_m_s2[i],
            gyro_std_rad_s=imu.gyro_noise_std_rad_s,
            accel_std_m_s2=imu.accel_noise_std_m_s2,
        )

    gyro, acc = imu.angular_velocity_rad_s, imu.linear_acceleration_m_s2
    values = {
        "angular_velocity.x": gyro[:, 0],
        "angular_velocity.y": gyro[:, 1],
        "angular_velocity.z": gyro[:, 2],
        "linear_acceleration.x": acc[:, 0],
        "linear_acceleration.y": acc[:, 1],
        "linear_acceleration.z": acc[:, 2],
    }
    return TopicSeries(topic, tp.IMU, imu.t_ns, build(0), values, build)


def velocity_series(
    topic: str,
    t_ns: NDArray[np.int64],
    velocity_m_s: NDArray[np.float64],
    covariance_m2_s2: NDArray[np.float64] | None = None,
    *,
    frame_id: str = tp.MAP,
) -> TopicSeries | None:
    """TwistWithCovarianceStamped series of a linear velocity (M, 3) m/s in ``frame_id`` axes.

    Rows with a non-finite velocity are dropped (None when none is left); the angular part is
    unmeasured (variance :data:`messages.UNKNOWN_ANGULAR_VARIANCE`).
    """
    vcov = np.zeros((len(t_ns), 3, 3)) if covariance_m2_s2 is None else covariance_m2_s2
    rows = np.flatnonzero(np.all(np.isfinite(velocity_m_s), axis=1))
    if not rows.size:
        return None
    t_v = t_ns[rows]
    vel_r = np.ascontiguousarray(velocity_m_s[rows], dtype=np.float64)
    vcov_r = np.ascontiguousarray(vcov[rows], dtype=np.float64).reshape(-1, 9)

    def build(i: int) -> Any:
        return mb.twist_with_covariance_stamped(
            int(t_v[i]), vel_r[i], vcov_r[i], frame_id=frame_id
        )

    cov36 = np.zeros((rows.size, 6, 6))
    cov36[:, :3, :3] = vcov_r.reshape(-1, 3, 3)
    cov36[:, 3:, 3:] = np.eye(3) * mb.UNKNOWN_ANGULAR_VARIANCE
    values = {
        "twist.twist.linear.x": vel_r[:, 0],
        "twist.twist.linear.y": vel_r[:, 1],
        "twist.twist.linear.z": vel_r[:, 2],
        "twist.covariance": cov36.reshape(-1, 36),
    }
    return TopicSeries(topic, tp.TWIST_WITH_COVARIANCE_STAMPED, t_v, build(0), values, build)


def odometry_series(
    topic: str,
    t_ns: NDArray[np.int64],
    position_m: NDArray[np.float64],
    orientation_xyzw: NDArray[np.float64],
    linear_m_s: NDArray[np.float64],
    angular_rad_s: NDArray[np.float64],
    *,
    pose_covariance: NDArray[np.float64] | None = None,
    twist_covariance: NDArray[np.float64] | None = None,
) -> TopicSeries:
    """Odometry series: pose (M, 3) m and (M, 4) xyzw in ``map``, twist (M, 3) in base_link.

    Covariances are (M, 6, 6) or None (zero, as on the truth topics).
    """
    n = len(t_ns)
    pos = np.ascontiguousarray(position_m, dtype=np.float64).reshape(n, 3)
    quat = np.ascontiguousarray(orientation_xyzw, dtype=np.float64).reshape(n, 4)
    lin = np.ascontiguousarray(linear_m_s, dtype=np.float64).reshape(n, 3)
    ang = np.ascontiguousarray(angular_rad_s, dtype=np.float64).reshape(n, 3)
    pcov = None if pose_covariance is None else np.asarray(pose_covariance).reshape(n, 36)
    tcov = None if twist_covariance is None else np.asarray(twist_covariance).reshape(n, 36)

    def build(i: int) -> Any:
        return mb.odometry(
            int(t_ns[i]),
            pos[i],
            quat[i],
            lin[i],
            ang[i],
            pose_covariance=None if pcov is None else pcov[i],
            twist_covariance=None if tcov is None else tcov[i],
        )

    values: dict[str, NDArray[Any]] = {}
    for k, axis in enumerate("xyz"):
        values[f"pose.pose.position.{axis}"] = pos[:, k]
        values[f"twist.twist.linear.{axis}"] = lin[:, k]
        values[f"twist.twist.angular.{axis}"] = ang[:, k]
    for k, axis in enumerate("xyzw"):
        values[f"pose.pose.orientation.{axis}"] = quat[:, k]
    if pcov is not None:
        values["pose.covariance"] = np.ascontiguousarray(pcov, dtype=np.float64)
    if tcov is not None:
        values["twist.covariance"] = np.ascontiguousarray(tcov, dtype=np.float64)
    return TopicSeries(topic, tp.ODOMETRY, t_ns, build(0), values, build)


def sim_topic_series(result: SimResult) -> list[TopicSeries]:
    """Every topic of the contract bag of ``result`` (inputs, then truth)."""
    out: list[TopicSeries] = []
    ws = result.wheel_speeds
    out.append(joint_series(tp.WHEEL_SPEEDS, ws.t_ns, WHEELS, "velocity", ws.wheel_speed_rad_s))
    st = result.steering
    out.append(
        joint_series(tp.STEERING, st.t_ns, ("front_wheel_angle",), "position", st.angle_rad)
    )

    out.append(imu_series(result.imu))

    g = result.gnss
    out.append(
        fix_series(
            tp.GNSS_FIX,
            g.t_ns,
            g.lat_deg,
            g.lon_deg,
            g.alt_m,
            g.position_covariance_m2,
            tp.GNSS_FRAME,
        )
    )
    if g.velocity_enu_m_s is not None:
        vel_series = velocity_series(
            tp.GNSS_VELOCITY, g.t_ns, g.velocity_enu_m_s, g.velocity_covariance_m2_s2
        )
        if vel_series is not None:
            out.append(vel_series)

    if result.tire_forces is not None:
        tf = result.tire_forces

        def build_tf(i: int) -> Any:
            return mb.tire_forces(
                int(tf.t_ns[i]), WHEELS, tf.fx_n[i], tf.fy_n[i], tf.fz_n[i], tf.valid[i]
            )

        tf_values = {"fx_n": tf.fx_n, "fy_n": tf.fy_n, "fz_n": tf.fz_n, "valid": tf.valid}
        out.append(
            TopicSeries(
                tp.TIRE_FORCES_TOPIC, tp.TIRE_FORCES, tf.t_ns, build_tf(0), tf_values, build_tf
            )
        )

    tr = result.truth
    zeros = np.zeros((len(tr.t_ns), 3, 3))
    out.append(
        fix_series(tp.TRUTH_FIX, tr.t_ns, tr.lat_deg, tr.lon_deg, tr.alt_m, zeros, tp.BASE_LINK)
    )
    half = 0.5 * tr.yaw_rad
    quat = np.stack([np.zeros_like(half), np.zeros_like(half), np.sin(half), np.cos(half)], 1)
    linear = np.column_stack([tr.velocity_m_s[:, 0], tr.velocity_m_s[:, 1], np.zeros(len(half))])
    angular = np.column_stack([np.zeros((len(half), 2)), tr.yaw_rate_rad_s])
    out.append(
        odometry_series(tp.TRUTH_ODOMETRY, tr.t_ns, tr.position_enu_m, quat, linear, angular)
    )

    stiff_names: tuple[str, ...] = tp.STIFFNESS_NAMES
    stiffness = tr.stiffness
    if tr.cx_rear_n is not None:
        stiff_names = tp.TRUTH_STIFFNESS_NAMES
        stiffness = np.column_stack([tr.stiffness, tr.cx_rear_n])
    stiff_tol = TRUTH_STIFFNESS_REL_TOL * np.maximum(np.nanmax(np.abs(stiffness), axis=0), 1.0)
    for topic, names, data, tol in (
        (tp.TRUTH_WHEEL_RADII, WHEELS, tr.wheel_radius_m, TRUTH_RADIUS_TOL_M),
        (tp.TRUTH_TIRE_PRESSURE, WHEELS, tr.tire_pressure_pa, TRUTH_PRESSURE_TOL_PA),
        (tp.TRUTH_TIRE_STIFFNESS, stiff_names, stiffness, stiff_tol),
    ):
        rows = reduced_rate_rows(tr.t_ns, data, tol)
        out.append(joint_series(topic, tr.t_ns[rows], tuple(names), "position", data[rows]))
    return out


def _plain(obj: Any) -> Any:
    """Convert to YAML-safe builtins (NumPy scalars/arrays, tuples, dataclasses, paths)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return _plain(dataclasses.asdict(obj))
    if isinstance(obj, Mapping):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    return obj


def sim_config_dict(result: SimResult) -> dict[str, Any]:
    """Content of ``sim_config.yaml``: scenario, seed, origin, duration (s), events, config."""
    return {
        "scenario": result.scenario,
        "seed": int(result.seed),
        "origin_lla": [float(v) for v in result.origin_lla],
        "duration_s": float(result.duration_s),
        "events": [
            {"t_s": float(e.t_s), "kind": e.kind, "detail": _plain(e.detail)}
            for e in result.events
        ],
        "config": _plain(result.config),
    }


def _check_target(out_dir: Path, overwrite: bool) -> None:
    if not out_dir.exists():
        return
    if not overwrite:
        raise BagError(f"{out_dir} exists; pass overwrite=True to replace it")
    if out_dir.is_dir() and any(out_dir.iterdir()) and not (out_dir / "metadata.yaml").exists():
        raise BagError(f"{out_dir} is a non-empty directory that is not a bag; not overwriting")


def _place_bag(out_dir: Path, overwrite: bool, fill: Callable[[Path], None]) -> Path:
    """Create the bag directory ``out_dir`` with ``fill(tmp_bag)`` in a hidden staging directory
    and rename it into place only when complete (replacing an old bag when ``overwrite``)."""
    _check_target(out_dir, overwrite)
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    staging = out_dir.parent / f".{out_dir.name}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    staging.mkdir()
    try:
        bag = staging / out_dir.name
        fill(bag)
        if out_dir.exists():
            _check_target(out_dir, overwrite)
            trash = staging / f"{out_dir.name}.old"
            out_dir.rename(trash)
        bag.rename(out_dir)
    except OSError as exc:
        raise BagError(f"cannot write bag {out_dir}: {exc}") from exc
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return out_dir


def write_sim_bag(
    result: SimResult,
    out_dir: Path | str,
    *,
    overwrite: bool = False,
    compression: bool = True,
    fast: bool = True,
) -> Path:
    """Write ``result`` as a contract bag directory ``out_dir`` and return its path.

    Args:
        result: simulated drive.
        out_dir: bag directory to create (holds ``metadata.yaml``, ``<name>.mcap``,
            ``vehicle.yaml`` and ``sim_config.yaml``).
        overwrite: replace an existing bag at ``out_dir`` (only once the new one is complete).
        compression: zstd-compress the MCAP chunks (readable by rosbags and rosbag2).
        fast: serialize with the bulk template encoder (byte-identical to rosbags' serializer).

    Raises:
        BagError: ``out_dir`` exists (without ``overwrite``) or the bag cannot be written.
    """
    custom = {
        CUSTOM_CONTRACT: "v1",
        CUSTOM_VEHICLE: yaml.safe_dump({"vehicle": result.vehicle.to_dict()}, sort_keys=False),
        CUSTOM_SCENARIO: result.scenario,
        CUSTOM_SEED: str(int(result.seed)),
        CUSTOM_ORIGIN: yaml.safe_dump([float(v) for v in result.origin_lla]),
        CUSTOM_EVENTS: yaml.safe_dump(sim_config_dict(result)["events"], sort_keys=False),
    }

    def fill(bag: Path) -> None:
        _write_bag(bag, sim_topic_series(result), custom, compression=compression, fast=fast)
        dump_vehicle_yaml(
            result.vehicle,
            bag / VEHICLE_FILE,
            comment=f"Vehicle of simulated scenario {result.scenario!r} (seed {result.seed}).",
        )
        (bag / SIM_CONFIG_FILE).write_text(
            yaml.safe_dump(sim_config_dict(result), sort_keys=False)
        )

    return _place_bag(Path(out_dir), overwrite, fill)


def write_contract_bag(
    out_dir: Path | str,
    vehicle: VehicleParams,
    series: list[TopicSeries],
    *,
    vehicle_comment: str = "",
    custom_data: Mapping[str, str] | None = None,
    extra_files: Mapping[str, str | bytes] | None = None,
    overwrite: bool = False,
    compression: bool = True,
    fast: bool = True,
) -> Path:
    """Write any set of topic series as a contract bag directory ``out_dir``; return its path.

    Args:
        out_dir: bag directory to create (``metadata.yaml``, ``<name>.mcap``, ``vehicle.yaml``
            and the ``extra_files``).
        vehicle: written to ``vehicle.yaml`` (with ``vehicle_comment`` as its header comment)
            and to the ``tire_estimation.vehicle`` custom data.
        series: the topics (see :class:`TopicSeries`); header stamps = log times.
        custom_data: more ``metadata.yaml`` custom data (string values); the contract version
            and the vehicle are added.
        extra_files: file name -> content of more files in the bag directory (text or bytes).
        overwrite, compression, fast: as in :func:`write_sim_bag`.

    Raises:
        BagError: ``out_dir`` exists (without ``overwrite``), a topic is given twice, a file
            name is not a plain name, or the bag cannot be written.
    """
    topics = [s.topic for s in series]
    if len(set(topics)) != len(topics):
        raise BagError(f"write_contract_bag: duplicate topic in {topics}")
    files = dict(extra_files or {})
    for name in files:
        if Path(name).name != name or name in (VEHICLE_FILE, "metadata.yaml"):
            raise BagError(f"write_contract_bag: invalid extra file name {name!r}")
    custom = {
        CUSTOM_CONTRACT: "v1",
        CUSTOM_VEHICLE: yaml.safe_dump({"vehicle": vehicle.to_dict()}, sort_keys=False),
        **{str(k): str(v) for k, v in (custom_data or {}).items()},
    }

    def fill(bag: Path) -> None:
        _write_bag(bag, series, custom, compression=compression, fast=fast)
        dump_vehicle_yaml(vehicle, bag / VEHICLE_FILE, comment=vehicle_comment)
        for name, content in files.items():
            if isinstance(content, bytes):
                (bag / name).write_bytes(content)
            else:
                (bag / name).write_text(content)

    return _place_bag(Path(out_dir), overwrite, fill)


def _write_bag(
    bag: Path,
    series: list[TopicSeries],
    custom: Mapping[str, str],
    *,
    compression: bool,
    fast: bool,
) -> None:
    store = get_typestore()
    payloads = [s.serialize(fast=fast) for s in series]
    times = np.concatenate([s.t_ns for s in series])
    topic_idx = np.concatenate([np.full(len(s.t_ns), k) for k, s in enumerate(series)])
    row_idx = np.concatenate([np.arange(len(s.t_ns)) for s in series])
    order = np.lexsort((row_idx, topic_idx, times))

    writer = Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP)
    if compression:
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    for key, value in custom.items():
        writer.set_custom_data(key, value)
    try:
        writer.open()
        conns = [writer.add_connection(s.topic, s.msgtype, typestore=store) for s in series]
        write = writer.write
        for t, k, i in zip(
            times[order].tolist(), topic_idx[order].tolist(), row_idx[order].tolist(), strict=True
        ):
            write(conns[k], t, payloads[k][i])
        writer.close()
    except Exception as exc:
        if writer.storage is not None:
            writer.abort()
        raise BagError(f"cannot write bag {bag.name}: {exc}") from exc
