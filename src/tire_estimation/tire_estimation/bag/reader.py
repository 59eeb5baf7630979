"""Read a contract bag into the stream dataclasses of :mod:`tire_estimation.sim.streams`.

:func:`read_bag` reads every (or the selected) contract topic of a rosbag2 bag (MCAP or sqlite3,
compressed or not) and returns :class:`BagData`. Messages are decoded in bulk with
:mod:`tire_estimation.bag.cdr` (NumPy over batches of same-layout messages), falling back to the
``rosbags`` deserializer for messages that do not fit a batch layout. Stream times are header
stamps (ns), sorted; samples with a repeated stamp are dropped (noted in :attr:`BagData.notes`).

Bad input messages are dropped and counted in :attr:`BagData.dropped` as ``<stream>:<kind>``,
the names the estimator node counts on ``/diagnostics``: a repeated stamp (``duplicate``), a
JointState or TireForces naming a wheel twice (``duplicate_wheel``, ``duplicate_joint``), and
every GNSS fix and velocity the node's check refuses (:meth:`GnssFix.from_navsat`,
:meth:`GnssVelocity.checked`: ``no_fix``, ``bad_covariance``, ``nan``, ...). The other bad
values of the high-rate streams reach the estimators, which drop and count them under the same
names.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray
from rosbags.rosbag2 import Reader

from tire_estimation.bag import topics as tp
from tire_estimation.bag.cdr import Batch, decode
from tire_estimation.bag.mcap_raw import McapFormatError, RawMessages, assemble, iter_mcap
from tire_estimation.bag.sim_config import events_from_text, read_sim_config
from tire_estimation.bag.typestore import bag_typestore
from tire_estimation.bag.writer import CUSTOM_EVENTS, CUSTOM_VEHICLE, SIM_CONFIG_FILE, VEHICLE_FILE
from tire_estimation.core import yamlio
from tire_estimation.core.arrays import F64, I64
from tire_estimation.core.input_checks import drop_key, unique_names
from tire_estimation.core.samples import STATUS_NO_FIX, GnssFix, GnssVelocity
from tire_estimation.core.vehicle import VehicleParams, load_vehicle_yaml, vehicle_from_document
from tire_estimation.core.wheels import CONTRACT_NAMES, WHEELS, Names
from tire_estimation.errors import BagError, InputError, VehicleConfigError
from tire_estimation.sim.streams import (
    GnssStream,
    GnssVelocityStream,
    ImuStream,
    SimEvent,
    SpeedStream,
    SteeringStream,
    TireForceStream,
    WheelSpeedStream,
)

_NS_PER_S = 1_000_000_000


@dataclass
class ReadLog:
    """What reading dropped: remarks (:attr:`notes`) and, for the input topics, counts by
    ``<stream>:<kind>`` (``dropped``). A remark made again (a bag read window by window) is
    kept once, with the counts added up."""

    dropped: Counter[str] = field(default_factory=Counter)
    _remarks: dict[tuple[str, str], int] = field(default_factory=dict)

    def drop(self, topic: str, kind: str, count: int, note: str) -> None:
        """``count`` messages of ``topic`` dropped as ``kind``; ``note`` says why."""
        if count <= 0:
            return
        key = (topic, note)
        self._remarks[key] = self._remarks.get(key, 0) + count
        stream = tp.INPUT_STREAMS.get(topic)
        if stream is not None:
            self.dropped[drop_key(stream, kind)] += count

    def remark(self, text: str) -> None:
        """A remark about the data that is not a count of dropped messages."""
        self._remarks.setdefault((text, ""), 0)

    @property
    def notes(self) -> list[str]:
        """The remarks, in the order first made."""
        return [
            f"{topic}: dropped {n} {note}" if note else topic
            for (topic, note), n in self._remarks.items()
        ]


@dataclass(frozen=True)
class TopicInfo:
    """A topic of the bag: message type and number of messages."""

    msgtype: str
    count: int


@dataclass(frozen=True)
class JointArrays:
    """A JointState topic as arrays: ``values`` (M, len(names)) by name, NaN where absent."""

    t_ns: I64
    names: tuple[str, ...]
    values: F64


@dataclass(frozen=True)
class OdometryArrays:
    """An Odometry topic as arrays (pose in ``frame_id``, twist in ``child_frame_id``).

    ``position_m`` (M, 3) m; ``orientation_xyzw`` (M, 4); ``yaw_rad`` (M,) rad (heading of x,
    counter-clockwise from the frame's x axis); ``linear_velocity_m_s`` (M, 3) m/s;
    ``angular_velocity_rad_s`` (M, 3) rad/s; covariances (M, 6, 6) in SI units squared.
    """

    t_ns: I64
    position_m: F64
    orientation_xyzw: F64
    yaw_rad: F64
    linear_velocity_m_s: F64
    angular_velocity_rad_s: F64
    pose_covariance: F64
    twist_covariance: F64
    frame_id: str
    child_frame_id: str


@dataclass(frozen=True)
class BagData:
    """Everything :func:`read_bag` found; a stream is None when its topic is absent/unread.

    ``start_ns``: first log time of the bag, ns; ``duration_s``: last minus first log time, s.
    ``topics``: every topic of the bag (read or not) with type and message count.
    ``events``, ``scenario``, ``seed``, ``sim_config``: from ``sim_config.yaml`` (simulated bags).
    ``notes``: human-readable remarks about data that was dropped while reading.
    ``dropped``: input messages dropped while reading, by ``<stream>:<kind>``.
    """

    path: Path
    vehicle: VehicleParams
    start_ns: int
    duration_s: float
    topics: dict[str, TopicInfo]
    wheel_speeds: WheelSpeedStream | None = None
    steering: SteeringStream | None = None
    imu: ImuStream | None = None
    gnss: GnssStream | None = None
    gnss_velocity: GnssVelocityStream | None = None
    tire_forces: TireForceStream | None = None
    vehicle_velocity: SpeedStream | None = None
    truth_fix: GnssStream | None = None
    truth_odometry: OdometryArrays | None = None
    truth_wheel_radii: JointArrays | None = None
    truth_tire_pressure: JointArrays | None = None
    truth_stiffness: JointArrays | None = None
    reference_odometry: OdometryArrays | None = None
    reference_lateral: JointArrays | None = None
    events: tuple[SimEvent, ...] = ()
    scenario: str | None = None
    seed: int | None = None
    sim_config: dict[str, Any] = field(default_factory=dict)
    custom_data: dict[str, str] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    dropped: dict[str, int] = field(default_factory=dict)

    def t_s(self, t_ns: I64) -> F64:
        """Seconds from the start of the bag."""
        return (np.asarray(t_ns, dtype=np.int64) - self.start_ns) * 1e-9


@dataclass
class RawTopic:
    """Undecoded messages of one topic, in bag (log-time) order.

    The payloads are ``data`` (one bytes object per message) or, when ``rows`` is set, the
    ``(M, length)`` uint8 array of messages that all have one length (``data`` then empty).
    """

    msgtype: str
    log_ns: I64 = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    data: list[bytes] = field(default_factory=list)
    rows: NDArray[np.uint8] | None = None
    #: encoding and text of the topic's schema in the bag, if the reader saw one
    schema: tuple[str, str] = ("", "")

    @property
    def payloads(self) -> Sequence[bytes] | NDArray[np.uint8]:
        """The serialized messages, as :func:`tire_estimation.bag.cdr.decode` takes them."""
        return self.rows if self.rows is not None else self.data

    def __len__(self) -> int:
        return len(self.rows) if self.rows is not None else len(self.data)


# --------------------------------------------------------------------------- raw access


def _bag_error(path: Path, exc: BaseException) -> BagError:
    return BagError(f"cannot read bag {path}: {type(exc).__name__}: {exc}".replace("\n", " "))


def open_reader(path: Path) -> Reader:
    """Open ``path`` (bag directory, ``.mcap`` or ``.db3``) with rosbags; BagError otherwise."""
    if not path.exists():
        raise BagError(f"bag not found: {path}")
    if path.is_dir() and not (path / "metadata.yaml").exists():
        raise BagError(f"not a rosbag2 bag (no metadata.yaml): {path}")
    try:
        reader = Reader(path)
        reader.open()
    except Exception as exc:  # ReaderError, OSError, struct/zstd/lz4/sqlite errors of bad files
        raise _bag_error(path, exc) from exc
    return reader


def mcap_files(path: Path) -> list[Path] | None:
    """The MCAP files of a bag whose messages :mod:`.mcap_raw` can read (plain ``.mcap``
    storage, no file- or message-level compression); None for any other bag."""
    if path.is_file():
        return [path] if path.suffix == ".mcap" else None
    try:
        info = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        if info.get("storage_identifier") != "mcap" or info.get("compression_mode") not in (
            "",
            None,
        ):
            return None
        files = [path / str(name) for name in info["relative_file_paths"]]
    except (OSError, yaml.YAMLError, KeyError, TypeError):
        return None
    return files if files and all(f.suffix == ".mcap" and f.is_file() for f in files) else None


class _Window:
    """Raw messages gathered per topic until they span a window of log time."""

    def __init__(self) -> None:
        self.parts: dict[str, list[RawMessages]] = {}
        self.first_ns: int | None = None
        self.last_ns: int | None = None

    def add(self, topic: str, msgs: RawMessages) -> None:
        parts = self.parts.setdefault(topic, [])
        if len(msgs) == 0:
            if not parts:
                parts.append(msgs)  # the topic is in the bag (its schema)
            return
        if parts and len(parts[0]) == 0:
            parts.clear()
        parts.append(msgs)
        lo, hi = int(msgs.log_ns.min()), int(msgs.log_ns.max())
        self.first_ns = lo if self.first_ns is None else min(self.first_ns, lo)
        self.last_ns = hi if self.last_ns is None else max(self.last_ns, hi)

    def full(self, window_ns: int | None) -> bool:
        return (
            window_ns is not None
            and self.first_ns is not None
            and self.last_ns is not None
            and self.last_ns - self.first_ns >= window_ns
        )

    def topics(self) -> dict[str, RawTopic]:
        out: dict[str, RawTopic] = {}
        for topic, parts in self.parts.items():
            first = parts[0]
            msgs = first if len(parts) == 1 else assemble(first.msgtype, parts)
            out[topic] = RawTopic(first.msgtype, msgs.log_ns, msgs.data or [], msgs.rows,
                                  schema=first.schema)  # fmt: skip
        return out


def iter_raw_fast(
    path: Path, files: list[Path], topics: Iterable[str], window_ns: int | None = None
) -> Iterator[dict[str, RawTopic]]:
    """Like :func:`iter_raw` but walking the MCAP files directly (see :mod:`.mcap_raw`)."""
    wanted = tuple(topics)
    window = _Window()
    for file in files:
        try:
            for found in iter_mcap(file, wanted):
                for topic, msgs in found.items():
                    window.add(topic, msgs)
                if window.full(window_ns):
                    yield window.topics()
                    window = _Window()
        except (McapFormatError, OSError) as exc:
            raise _bag_error(path, exc) from exc
    yield window.topics()


def read_raw_fast(path: Path, files: list[Path], topics: Iterable[str]) -> dict[str, RawTopic]:
    """Like :func:`read_raw` but walking the MCAP files directly (see :mod:`.mcap_raw`)."""
    return next(iter_raw_fast(path, files, topics))


def iter_raw(
    reader: Reader, path: Path, topics: Iterable[str], window_ns: int | None = None
) -> Iterator[dict[str, RawTopic]]:
    """Serialized messages of ``topics`` (those present in the bag), grouped by topic, in
    windows that each span ``window_ns`` of log time (None: one window, the whole bag)."""
    wanted = set(topics)
    conns = [c for c in reader.connections if c.topic in wanted]
    msgtypes = {c.topic: c.msgtype for c in conns}

    def new() -> tuple[dict[str, list[int]], dict[str, list[bytes]]]:
        return {topic: [] for topic in msgtypes}, {topic: [] for topic in msgtypes}

    def topics_of(logs: dict[str, list[int]], data: dict[str, list[bytes]]) -> dict[str, RawTopic]:
        return {
            topic: RawTopic(msgtype, np.asarray(logs[topic], dtype=np.int64), data[topic])
            for topic, msgtype in msgtypes.items()
        }

    logs, data = new()
    if conns:
        first: int | None = None
        try:
            for conn, log_ns, payload in reader.messages(connections=conns):
                if window_ns is not None:
                    if first is None:
                        first = log_ns
                    elif log_ns - first >= window_ns:
                        yield topics_of(logs, data)
                        logs, data = new()
                        first = log_ns
                logs[conn.topic].append(log_ns)
                data[conn.topic].append(payload)
        except Exception as exc:  # ReaderError, zstd errors, struct.error, EOF on truncated files
            raise _bag_error(path, exc) from exc
    yield topics_of(logs, data)


def read_raw(reader: Reader, path: Path, topics: Iterable[str]) -> dict[str, RawTopic]:
    """Serialized messages of ``topics`` (those present in the bag), grouped by topic."""
    return next(iter_raw(reader, path, topics))


# --------------------------------------------------------------------------- decoding helpers


def _stamps(batch: Batch) -> I64:
    sec = batch.arrays["header.stamp.sec"].astype(np.int64)
    return sec * _NS_PER_S + batch.arrays["header.stamp.nanosec"].astype(np.int64)


def _all_stamps(batches: list[Batch], count: int) -> I64:
    t = np.zeros(count, dtype=np.int64)
    for b in batches:
        t[b.index] = _stamps(b)
    return t


def _column(batches: list[Batch], count: int, path: str, width: int | None = None) -> F64:
    shape = (count,) if width is None else (count, width)
    out = np.full(shape, np.nan)
    for b in batches:
        out[b.index] = b.arrays[path]
    return out


def _order(t_ns: I64, what: str, log: ReadLog, bad: NDArray[np.bool_] | None = None) -> I64:
    """Indices sorting ``t_ns`` (stable) and keeping the first of repeated stamps, without the
    rows marked ``bad`` (dropped and counted by the caller)."""
    order = np.argsort(t_ns, kind="stable")
    if bad is not None:
        order = order[~bad[order]]
    t_sorted = t_ns[order]
    keep = np.ones(t_sorted.size, dtype=bool)
    keep[1:] = np.diff(t_sorted) > 0
    dropped = int(t_sorted.size - keep.sum())
    log.drop(what, "duplicate", dropped, "messages with a repeated header stamp")
    if np.any(np.diff(t_ns) < 0):
        log.remark(f"{what}: messages were not in header-stamp order; sorted")
    return order[keep]


def _by_name(
    batches: list[Batch],
    count: int,
    names_path: str,
    value_paths: Sequence[str],
    names: Sequence[str],
    fill: float = np.nan,
) -> tuple[list[F64], NDArray[np.bool_]]:
    """Per-name columns of parallel arrays (JointState-like); absent names stay ``fill``; and
    the rows whose message names one of ``names`` more than once (not filled)."""
    index = {n: i for i, n in enumerate(names)}
    outs = [np.full((count, len(names)), fill) for _ in value_paths]
    repeated = np.zeros(count, dtype=bool)
    for b in batches:
        msg_names = b.strings.get(names_path, ())
        try:
            unique_names(msg_names, index, "duplicate")
        except InputError:
            repeated[b.index] = True
            continue
        for out, path in zip(outs, value_paths, strict=True):
            values = b.arrays[path]
            if values.shape[1] != len(msg_names):
                continue  # e.g. JointState without this field
            for j, name in enumerate(msg_names):
                if name in index:
                    out[b.index, index[name]] = values[:, j]
    return outs, repeated


def _drop_repeated(what: str, repeated: NDArray[np.bool_], log: ReadLog) -> None:
    """Count the messages that name a wheel (joint) twice: which value is meant is unknown."""
    wheels = what in (tp.WHEEL_SPEEDS, tp.TIRE_FORCES_TOPIC)
    kind = "duplicate_wheel" if wheels else "duplicate_joint"
    log.drop(what, kind, int(repeated.sum()), "messages that name a joint more than once")


def joint_arrays(
    batches: list[Batch],
    count: int,
    names: Sequence[str],
    value: str,
    what: str,
    log: ReadLog,
) -> JointArrays:
    """A JointState topic's ``value`` field (position/velocity/effort) matched by name.

    Raises BagError when no message of an input topic names any of ``names`` (a robot's own
    joint names that ``name_remaps`` does not map)."""
    found = {n for b in batches for n in b.strings.get("name", ())}
    if count and what in tp.INPUT_TOPICS and not found & set(names):
        shown = ", ".join(sorted(found)[:6]) or "none"
        raise BagError(
            f"{what}: no joint named {', '.join(names)} (the bag names {shown}); map the "
            "bag's names with the estimator parameter name_remaps"
        )
    t = _all_stamps(batches, count)
    (values,), repeated = _by_name(batches, count, "name", [value], names)
    _drop_repeated(what, repeated, log)
    keep = _order(t, what, log, repeated)
    return JointArrays(t[keep], tuple(names), values[keep])


def imu_stream(batches: list[Batch], count: int, log: ReadLog) -> ImuStream:
    """``sensor_msgs/Imu`` messages as :class:`ImuStream` (noise std from the covariances)."""
    t = _all_stamps(batches, count)
    gyro = np.column_stack([_column(batches, count, f"angular_velocity.{a}") for a in "xyz"])
    acc = np.column_stack([_column(batches, count, f"linear_acceleration.{a}") for a in "xyz"])
    keep = _order(t, tp.IMU_DATA, log)

    def std(path: str) -> float:
        diag = batches[0].arrays[path][0][[0, 4, 8]]
        return float(math.sqrt(np.mean(diag))) if np.all(diag > 0) else 0.0

    return ImuStream(
        t[keep],
        gyro[keep],
        acc[keep],
        gyro_noise_std_rad_s=std("angular_velocity_covariance"),
        accel_noise_std_m_s2=std("linear_acceleration_covariance"),
    )


def _refused(
    count: int, check: Callable[[int], None], what: str, log: ReadLog
) -> NDArray[np.bool_]:
    """The rows ``check`` refuses (raises InputError), dropped and counted by kind (before the
    repeated stamps: as the node, which checks each message as it comes)."""
    bad = np.zeros(count, dtype=bool)
    kinds: Counter[str] = Counter()
    for i in range(count):
        try:
            check(i)
        except InputError as exc:
            kinds[exc.kind] += 1
            bad[i] = True
    for kind, n in sorted(kinds.items()):
        log.drop(what, kind, n, f"messages refused by the input check ({kind})")
    return bad


def fix_stream(
    batches: list[Batch],
    count: int,
    what: str,
    log: ReadLog,
    velocity: tuple[I64, F64, F64] | None = None,
) -> GnssStream | None:
    """``sensor_msgs/NavSatFix`` messages as :class:`GnssStream` (no-fix messages dropped).

    The fixes of the input topic are checked as the node checks them
    (:meth:`GnssFix.from_navsat`): a refused fix is dropped and counted, a covariance of type
    unknown is stored all zero (not reported), a missing altitude as NaN. ``velocity`` (t_ns,
    (K, 3), (K, 3, 3)) is matched to the fixes by identical stamp; fixes without a velocity get
    NaN rows.
    """
    t = _all_stamps(batches, count)
    status = _column(batches, count, "status.status")
    lat = _column(batches, count, "latitude")
    lon = _column(batches, count, "longitude")
    alt = _column(batches, count, "altitude")
    cov = _column(batches, count, "position_covariance", 9).reshape(-1, 3, 3)
    if what == tp.GNSS_FIX:
        cov_type = _column(batches, count, "position_covariance_type")

        def check(i: int) -> None:
            fix = GnssFix.from_navsat(
                int(t[i]), status[i], lat[i], lon[i], alt[i], cov[i], cov_type[i]
            )
            alt[i] = fix.alt_m
            cov[i] = 0.0 if fix.covariance_m2 is None else fix.covariance_m2

        bad = _refused(count, check, what, log)
    else:
        bad = status == STATUS_NO_FIX
        log.drop(what, "no_fix", int(bad.sum()), "messages with STATUS_NO_FIX")
    good = _order(t, what, log, bad)
    if good.size == 0:
        return None
    vel = vcov = None
    if velocity is not None:
        t_v, v, c = velocity
        pos = np.clip(np.searchsorted(t_v, t[good]), 0, max(len(t_v) - 1, 0))
        hit = (t_v[pos] == t[good]) if len(t_v) else np.zeros(good.size, dtype=bool)
        vel = np.full((good.size, 3), np.nan)
        vcov = np.full((good.size, 3, 3), np.nan)
        vel[hit] = v[pos[hit]]
        vcov[hit] = c[pos[hit]]
        if not hit.all():
            log.remark(f"{what}: {int((~hit).sum())} fixes have no velocity at their stamp")
    return GnssStream(t[good], lat[good], lon[good], alt[good], cov[good], vel, vcov)


def velocity_arrays(
    batches: list[Batch], count: int, log: ReadLog, what: str = tp.GNSS_VELOCITY
) -> tuple[I64, F64, F64]:
    """A ``TwistWithCovarianceStamped`` topic (``/gnss/velocity``: ENU) as (t_ns, linear
    velocity (K, 3) m/s, covariance (K, 3, 3) m^2/s^2). The GNSS velocities are checked as the
    node checks them (:meth:`GnssVelocity.checked`): a refused one is dropped and counted (an
    all-zero covariance is not given)."""
    t = _all_stamps(batches, count)
    vel = np.column_stack([_column(batches, count, f"twist.twist.linear.{a}") for a in "xyz"])
    cov = _column(batches, count, "twist.covariance", 36).reshape(-1, 6, 6)[:, :3, :3]
    cov = np.ascontiguousarray(cov)
    bad = None
    if what == tp.GNSS_VELOCITY:

        def check(i: int) -> None:
            GnssVelocity.checked(int(t[i]), vel[i], cov[i])

        bad = _refused(count, check, what, log)
    keep = _order(t, what, log, bad)
    return t[keep], vel[keep], cov[keep]


def tire_force_stream(
    batches: list[Batch], count: int, log: ReadLog, wheels: Sequence[str] = WHEELS
) -> TireForceStream:
    """``tire_estimation_msgs/TireForces`` by wheel name (``wheels``: the names of
    ``wheel_fl`` ... ``wheel_rr``); absent wheels NaN and not valid."""
    t = _all_stamps(batches, count)
    (fx, fy, fz), repeated = _by_name(
        batches, count, "wheel_names", ["fx_n", "fy_n", "fz_n"], wheels
    )
    (valid,), _ = _by_name(batches, count, "wheel_names", ["valid"], wheels, fill=0.0)
    _drop_repeated(tp.TIRE_FORCES_TOPIC, repeated, log)
    keep = _order(t, tp.TIRE_FORCES_TOPIC, log, repeated)
    return TireForceStream(t[keep], fx[keep], fy[keep], fz[keep], valid[keep] > 0.5)


def odometry_arrays(batches: list[Batch], count: int, what: str, log: ReadLog) -> OdometryArrays:
    """``nav_msgs/Odometry`` messages as :class:`OdometryArrays`."""
    t = _all_stamps(batches, count)
    pos = np.column_stack([_column(batches, count, f"pose.pose.position.{a}") for a in "xyz"])
    quat = np.column_stack([_column(batches, count, f"pose.pose.orientation.{a}") for a in "xyzw"])
    lin = np.column_stack([_column(batches, count, f"twist.twist.linear.{a}") for a in "xyz"])
    ang = np.column_stack([_column(batches, count, f"twist.twist.angular.{a}") for a in "xyz"])
    pcov = _column(batches, count, "pose.covariance", 36).reshape(-1, 6, 6)
    tcov = _column(batches, count, "twist.covariance", 36).reshape(-1, 6, 6)
    keep = _order(t, what, log)
    x, y, z, w = quat[keep].T
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    first = batches[0].strings
    return OdometryArrays(
        t[keep],
        pos[keep],
        quat[keep],
        yaw,
        lin[keep],
        ang[keep],
        pcov[keep],
        tcov[keep],
        str(first.get("header.frame_id", "")),
        str(first.get("child_frame_id", "")),
    )


# --------------------------------------------------------------------------- metadata


def _bag_dir(path: Path) -> Path:
    return path if path.is_dir() else path.parent


def _custom_data(path: Path) -> dict[str, str]:
    meta = _bag_dir(path) / "metadata.yaml"
    if not path.is_dir() or not meta.exists():
        return {}
    try:
        info = yaml.safe_load(meta.read_text()) or {}
        custom = info.get("rosbag2_bagfile_information", {}).get("custom_data") or {}
    except (yaml.YAMLError, AttributeError):
        return {}
    return {str(k): str(v) for k, v in custom.items()}


def find_vehicle(path: Path, custom: dict[str, str]) -> VehicleParams:
    """Vehicle of the bag: ``vehicle.yaml`` in the bag directory, next to the bag, else the
    ``tire_estimation.vehicle`` custom data of ``metadata.yaml``.

    Raises:
        BagError: no vehicle description at all.
        VehicleConfigError: a description that is malformed or absurd (names the field).
    """
    candidates = (
        [path / VEHICLE_FILE, path.parent / VEHICLE_FILE]
        if path.is_dir()
        else [path.parent / VEHICLE_FILE]
    )
    for candidate in candidates:
        if candidate.is_file():
            return load_vehicle_yaml(candidate)
    if CUSTOM_VEHICLE in custom:
        try:
            data = yamlio.safe_load(custom[CUSTOM_VEHICLE])
        except yaml.YAMLError as exc:
            reason = f"not valid YAML: {yamlio.describe(exc)}"
            raise VehicleConfigError(CUSTOM_VEHICLE, custom[CUSTOM_VEHICLE], reason) from exc
        return vehicle_from_document(data, f"metadata {CUSTOM_VEHICLE}")
    raise BagError(
        f"no vehicle.yaml for bag {path} (looked in {', '.join(map(str, candidates))} and "
        f"the metadata custom data key {CUSTOM_VEHICLE})"
    )


def _sim_config(path: Path, custom: dict[str, str]) -> tuple[dict[str, Any], tuple[SimEvent, ...]]:
    cfg_path = _bag_dir(path) / SIM_CONFIG_FILE
    if cfg_path.is_file():
        config, events = read_sim_config(cfg_path)
        if "events" in config or CUSTOM_EVENTS not in custom:
            return config, events
        return config, events_from_text(custom[CUSTOM_EVENTS], f"metadata {CUSTOM_EVENTS}")
    if CUSTOM_EVENTS in custom:
        return {}, events_from_text(custom[CUSTOM_EVENTS], f"metadata {CUSTOM_EVENTS}")
    return {}, ()


# --------------------------------------------------------------------------- read_bag

#: Topics :func:`read_bag` decodes by default.
READ_TOPICS = tp.INPUT_TOPICS + tp.TRUTH_TOPICS + tp.REFERENCE_TOPICS


def read_bag(
    path: Path | str,
    *,
    topics: Iterable[str] | Callable[[Mapping[str, TopicInfo]], Iterable[str]] | None = None,
    require: Iterable[str] = (),
    fast: bool = True,
    joints: Names = CONTRACT_NAMES,
) -> BagData:
    """Read a contract bag.

    Args:
        path: bag directory (or a single ``.mcap`` / ``.db3`` file).
        topics: contract topics to decode (default: all inputs, truth and reference); others
            are listed in :attr:`BagData.topics` but not decoded. A function instead is called
            with the bag's topics (name -> type and count) and returns the topics to decode,
            so that a caller decodes only what it will use.
        require: topics that must be present (BagError naming the first missing one).
        fast: decode with the bulk NumPy decoder (False: ``rosbags`` message by message).
        joints: the bag's joint names for the contract's wheels and steering joint.

    Raises:
        BagError: missing path, not a bag, unreadable/corrupt bag, a required topic missing,
            a contract topic with the wrong message type, or no vehicle description.
        VehicleConfigError: the vehicle description is malformed or absurd.
    """
    meta, selected, files = open_bag(path, topics=topics, require=require, fast=fast)
    if files is None:
        reader = open_reader(meta.path)
        try:
            raw = read_raw(reader, meta.path, selected)
        finally:
            reader.close()
    else:
        raw = read_raw_fast(meta.path, files, selected)
    return replace(meta, **decode_topics(raw, fast=fast, joints=joints))


def open_bag(
    path: Path | str,
    *,
    topics: Iterable[str] | Callable[[Mapping[str, TopicInfo]], Iterable[str]] | None = None,
    require: Iterable[str] = (),
    fast: bool = True,
) -> tuple[BagData, tuple[str, ...], list[Path] | None]:
    """What :func:`read_bag` knows before reading the messages: the bag's metadata as
    :class:`BagData` without streams, the topics to decode, and the MCAP files that
    :mod:`.mcap_raw` reads (None: read through ``rosbags``). Arguments and errors as there."""
    path = Path(path)
    if topics is not None and not callable(topics):
        _check_readable(tuple(topics))
    reader = open_reader(path)
    try:
        infos = {
            name: TopicInfo(info.msgtype or "", int(info.msgcount))
            for name, info in reader.topics.items()
        }
        if topics is None:
            selected: tuple[str, ...] = READ_TOPICS
        else:
            selected = tuple(topics(infos) if callable(topics) else topics)
            _check_readable(selected)
        for topic in require:
            if topic not in infos or infos[topic].count == 0:
                raise BagError(f"bag {path} has no messages on required topic {topic}")
        for topic in selected:
            if topic in infos and infos[topic].msgtype != tp.TOPIC_TYPES[topic]:
                raise BagError(
                    f"bag {path}: topic {topic} has type {infos[topic].msgtype}, "
                    f"expected {tp.TOPIC_TYPES[topic]}"
                )
        custom = _custom_data(path)
        vehicle = find_vehicle(path, custom)
        config, events = _sim_config(path, custom)
        start_ns = int(reader.start_time) if reader.message_count else 0
        end_ns = int(reader.end_time) - 1 if reader.message_count else 0
    finally:
        reader.close()
    files = mcap_files(path) if fast else None
    seed = config.get("seed")
    meta = BagData(
        path=path,
        vehicle=vehicle,
        start_ns=start_ns,
        duration_s=max(end_ns - start_ns, 0) * 1e-9,
        topics=infos,
        events=events,
        scenario=config.get("scenario"),
        seed=int(seed) if isinstance(seed, int) else None,
        sim_config=config,
        custom_data=custom,
    )
    return meta, selected, files


def _check_readable(selected: tuple[str, ...]) -> None:
    unknown = [t for t in selected if t not in tp.TOPIC_TYPES or t not in READ_TOPICS]
    if unknown:
        raise BagError(f"read_bag cannot decode topic {unknown[0]}")


#: the stream fields of :class:`BagData` :func:`decode_topics` fills, by topic
STREAM_FIELDS: dict[str, str] = {
    tp.WHEEL_SPEEDS: "wheel_speeds",
    tp.STEERING: "steering",
    tp.IMU_DATA: "imu",
    tp.GNSS_FIX: "gnss",
    tp.GNSS_VELOCITY: "gnss_velocity",
    tp.TIRE_FORCES_TOPIC: "tire_forces",
    tp.VEHICLE_VELOCITY: "vehicle_velocity",
    tp.TRUTH_FIX: "truth_fix",
    tp.TRUTH_ODOMETRY: "truth_odometry",
    tp.TRUTH_WHEEL_RADII: "truth_wheel_radii",
    tp.TRUTH_TIRE_PRESSURE: "truth_tire_pressure",
    tp.TRUTH_TIRE_STIFFNESS: "truth_stiffness",
    tp.REFERENCE_ODOMETRY: "reference_odometry",
    tp.REFERENCE_LATERAL_STATE: "reference_lateral",
}


def decode_topics(
    raw: dict[str, RawTopic],
    *,
    fast: bool = True,
    log: ReadLog | None = None,
    match_velocity: bool = True,
    joints: Names = CONTRACT_NAMES,
) -> dict[str, Any]:
    """Decode raw topics into the stream fields of :class:`BagData` (plus ``notes`` and
    ``dropped``, those of ``log`` when given: a log shared by the windows of one bag).
    ``match_velocity``: attach ``/gnss/velocity`` to the fixes of the same stamp
    (:attr:`GnssStream.velocity_enu_m_s`); False leaves the fixes without it."""
    store = bag_typestore(
        tuple(sorted({(rt.msgtype, *rt.schema) for rt in raw.values() if len(rt)}))
    )
    log = ReadLog() if log is None else log
    batches: dict[str, tuple[list[Batch], int]] = {}
    for topic, rt in raw.items():
        if len(rt):
            try:
                batches[topic] = (decode(store, rt.msgtype, rt.payloads, fast=fast), len(rt))
            except BagError as exc:
                raise BagError(f"topic {topic}: {exc}") from exc

    out: dict[str, Any] = {}
    if tp.WHEEL_SPEEDS in batches:
        ja = joint_arrays(
            *batches[tp.WHEEL_SPEEDS], joints.wheels, "velocity", tp.WHEEL_SPEEDS, log
        )
        out["wheel_speeds"] = WheelSpeedStream(ja.t_ns, ja.values)
    if tp.STEERING in batches:
        ja = joint_arrays(*batches[tp.STEERING], (joints.steering,), "position", tp.STEERING, log)
        out["steering"] = SteeringStream(ja.t_ns, ja.values[:, 0])
    if tp.IMU_DATA in batches:
        out["imu"] = imu_stream(*batches[tp.IMU_DATA], log)
    velocity = None
    if tp.GNSS_VELOCITY in batches:
        velocity = velocity_arrays(*batches[tp.GNSS_VELOCITY], log)
        out["gnss_velocity"] = GnssVelocityStream(*velocity)
    if tp.GNSS_FIX in batches:
        matched = velocity if match_velocity else None
        out["gnss"] = fix_stream(*batches[tp.GNSS_FIX], tp.GNSS_FIX, log, matched)
    if tp.TIRE_FORCES_TOPIC in batches:
        out["tire_forces"] = tire_force_stream(*batches[tp.TIRE_FORCES_TOPIC], log, joints.wheels)
    if tp.VEHICLE_VELOCITY in batches:
        t_v, vel, _ = velocity_arrays(*batches[tp.VEHICLE_VELOCITY], log, tp.VEHICLE_VELOCITY)
        out["vehicle_velocity"] = SpeedStream(t_v, np.ascontiguousarray(vel[:, 0]))
    if tp.TRUTH_FIX in batches:
        out["truth_fix"] = fix_stream(*batches[tp.TRUTH_FIX], tp.TRUTH_FIX, log)
    for topic, key in (
        (tp.TRUTH_ODOMETRY, "truth_odometry"),
        (tp.REFERENCE_ODOMETRY, "reference_odometry"),
    ):
        if topic in batches:
            out[key] = odometry_arrays(*batches[topic], topic, log)
    for topic, key, names in (
        (tp.TRUTH_WHEEL_RADII, "truth_wheel_radii", WHEELS),
        (tp.TRUTH_TIRE_PRESSURE, "truth_tire_pressure", WHEELS),
        (tp.TRUTH_TIRE_STIFFNESS, "truth_stiffness", tp.TRUTH_STIFFNESS_NAMES),
        (tp.REFERENCE_LATERAL_STATE, "reference_lateral", tp.REFERENCE_LATERAL_NAMES),
    ):
        if topic in batches:
            out[key] = joint_arrays(*batches[topic], names, "position", topic, log)
    out["notes"] = tuple(log.notes)
    out["dropped"] = dict(sorted(log.dropped.items()))
    return out
