"""Clearpath Husky drive (ROS 1 bag ``test1.bag`` of robot_localization) -> contract bag.

Input: a folder holding ``test1.bag`` (or the path of the bag itself), a ROS 1 bag read with
``rosbags.rosbag1`` (no ROS needed). Topics (checked on the real bag, see
``docs/data_husky.md``):

* ``/husky_velocity_controller/odom`` (nav_msgs/Odometry, 10 Hz, frame ``odom``, child frame
  ``base_link``): pose and twist of ros_controllers' ``diff_drive_controller`` from the two
  side travels the Husky MCU reports (the two wheels of a side are chained). The twist holds
  only ``linear.x`` and ``angular.z`` and is the rolling mean of the last 10 per-cycle
  velocities (1 s window); the pose is integrated from the raw per-cycle increments.
* ``/imu/data`` (sensor_msgs/Imu, 30 Hz, frame ``imu_link``): a "slightly broken Microstrain
  3DM-GX2" mounted rotated (comment of the robot_localization test below); gravity reads on its
  +y axis.
* ``/fix`` (sensor_msgs/NavSatFix, 2.5 Hz, frame ``/gps``): status 1 (SBAS), covariance type 1
  (approximated), diagonal, horizontal 0.64 ... 2.89 m^2.

Numbers of the robot and where they come from (the versions in use when the bag was recorded:
its header stamps, 1.4322e9 s Unix time, predate the change to the 13 inch tyre below):

* Wheel radius ``r = 0.17775 m``: ``wheel_radius`` in ``husky_description/urdf/husky.urdf.xacro``
  (repository husky/husky, commit 0cb42db), the radius of the wheel collision cylinder that
  ``diff_drive_controller`` reads, times ``wheel_radius_multiplier: 1.0`` of
  ``husky_control/config/control.yaml`` (husky/husky, commit ff35312). The hardware driver
  turns the MCU's side travel (m) into a wheel angle with ``wheel_diameter: 0.3555`` (=
  2 r) in ``husky_base/launch/base.launch`` (repository husky/husky_robot, commit 871922d), so
  the odometry speed is the MCU's speed and the angular speed written here,
  ``v_side / r``, is the joint velocity the controller saw. (The URDF and the driver were both
  changed later to the 13 inch outdoor tyre, r = 0.1651 m: husky/husky 176890d, husky/husky_robot
  f430806; not the software of this bag.)
* Effective wheel separation ``b_eff = 1.875 x 0.5708 m = 1.07025 m``:
  ``wheel_separation_multiplier: 1.875`` of the same ``control.yaml`` times the distance of
  the left and right wheel joints, ``track = 0.5708`` m of the same URDF (diff_drive_controller
  takes the separation from the URDF and multiplies it). Check in the data: the side travels
  ``s -+ b_eff dpsi / 2`` reconstructed from the pose increments are whole millimetres (the
  MCU's resolution) in every cycle with this ``b_eff``; with 0.5708, 1.0 or 1.1 m only in the
  40 % of cycles without a heading change.
* IMU mounting: ``static_transform_publisher`` ``0 -0.3 0.52 -1.570796327 0 1.570796327
  base_link imu_link`` (x y z yaw pitch roll) in ``test/test_ekf_localization_node_bag1.test``
  of cra-ros-pkg/robot_localization, the test that plays this bag: ``R = Rz(-pi/2) Rx(pi/2)``
  maps imu_link vectors into the Husky base_link, i.e. ``x_b = -z_i``, ``y_b = -x_i``,
  ``z_b = y_i`` (:data:`IMU_TO_BASE`). Confirmed by the data: gravity on imu +y; gyro ``y_i``
  against the odometry yaw rate gain +0.99 (corr 0.85); ``-x_i`` follows ``v r`` and
  ``-z_i`` follows ``dv/dt``.
* Geometry and mass: ``wheelbase = 0.5120`` m, ``wheel_vertical_offset = 0.03282`` m, chassis
  33.455 kg at (-0.08748, -0.00085, 0.09947) m from the Husky base_link with yaw inertia
  ``izz = 2.0296`` kg m^2, four wheels of 2.637 kg (same URDF and ``wheel.urdf.xacro``).

Conversion:

* Header stamps are the bags' header stamps in ns (ROS time of the recording machine).
* Frames: the contract base_link is the centre of the rear axle on the ground. The Husky
  base_link (centre of the chassis bottom plate) is ``wheelbase / 2`` ahead of it and
  ``r - wheel_vertical_offset = 0.14493`` m above the ground, so the IMU is at
  (0.256, -0.3, 0.665) m in the contract base_link.
* ``/vehicle/wheel_speeds``: side surface speeds ``v_l = v - w b_eff / 2``,
  ``v_r = v + w b_eff / 2`` (inverse of ``v = (v_l + v_r) / 2``, ``w = (v_r - v_l) / b_eff``),
  angular speed ``v_side / r`` rad/s, the left value on ``wheel_fl`` and ``wheel_rl``, the right
  one on ``wheel_fr`` and ``wheel_rr``. ``v`` and ``w`` come, by default (``source = "pose"``),
  from consecutive odometry poses: ``dpsi`` the heading increment, ``ds`` the travel along the
  mid heading divided by ``sinc(dpsi / 2)`` (the controller integrates each cycle as an arc),
  ``v = ds / dt``, ``w = dpsi / dt``, stamped at the middle of the cycle; this is the raw
  per-cycle travel without the twist's 1 s rolling mean (which lags by about 0.45 s). With
  ``source = "twist"`` the published twist is used at the message stamps instead.
* ``/imu/data``: ``IMU_TO_BASE`` applied to angular velocity and specific force (orientation
  not carried); diagonal covariances from first-difference noise estimates.
* ``/gnss/fix`` (frame ``gnss_antenna``): position and covariance copied (NavSatFix
  covariances are ENU m^2 by definition), covariance type kept; fixes without a fix status
  or with non-finite coordinates are dropped.
* No ``/vehicle/steering`` (skid steer), no reference (the bag has none; the controller's
  odometry is an input here, not a reference).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tire_estimation.bag import topics as tp
from tire_estimation.bag.writer import (
    TopicSeries,
    fix_series,
    imu_series,
    joint_series,
)
from tire_estimation.convert.common import (
    ConvertError,
    attribution,
    diff_noise_std,
    increasing_rows,
    write_converted_bag,
)
from tire_estimation.core.arrays import F64, I64
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.core.wheels import WHEELS
from tire_estimation.errors import ConfigError
from tire_estimation.sim.streams import ImuStream

WHAT = "husky bag"
BAG_FILE = "test1.bag"
ODOM_TOPIC = "/husky_velocity_controller/odom"
IMU_TOPIC = "/imu/data"
FIX_TOPIC = "/fix"
_TYPES = {
    ODOM_TOPIC: "nav_msgs/msg/Odometry",
    IMU_TOPIC: "sensor_msgs/msg/Imu",
    FIX_TOPIC: "sensor_msgs/msg/NavSatFix",
}

#: husky_description/urdf/husky.urdf.xacro (husky/husky 0cb42db): ``wheel_radius``, m.
URDF_WHEEL_RADIUS_M = 0.17775
#: same file: ``track`` (distance of the left and right wheel joints), m.
URDF_TRACK_M = 0.5708
#: same file: ``wheelbase``, m.
URDF_WHEELBASE_M = 0.5120
#: same file: ``wheel_vertical_offset`` (wheel axle above the Husky base_link), m.
URDF_WHEEL_VERTICAL_OFFSET_M = 0.03282
#: same file, ``inertial_link``: chassis mass (kg), its centre (m, Husky base_link), izz (kg m^2).
URDF_CHASSIS_MASS_KG = 33.455
URDF_CHASSIS_CENTRE_M = (-0.08748, -0.00085, 0.09947)
URDF_CHASSIS_IZZ_KG_M2 = 2.0296
#: husky_description/urdf/wheel.urdf.xacro: wheel mass (kg) and its inertia about a diameter
#: (``ixx``, the vertical axis of a rolling wheel), kg m^2.
URDF_WHEEL_MASS_KG = 2.637
URDF_WHEEL_DIAMETRAL_INERTIA_KG_M2 = 0.02467
#: husky_control/config/control.yaml (husky/husky ff35312).
WHEEL_SEPARATION_MULTIPLIER = 1.875
WHEEL_RADIUS_MULTIPLIER = 1.0
#: Radius the controller turned joint angles into travel with, m (= URDF radius x multiplier).
NOMINAL_WHEEL_RADIUS_M = URDF_WHEEL_RADIUS_M * WHEEL_RADIUS_MULTIPLIER
#: Effective (skid-steer) wheel separation of the controller's yaw rate, m: 1.07025.
EFFECTIVE_SEPARATION_M = WHEEL_SEPARATION_MULTIPLIER * URDF_TRACK_M
#: Height of the Husky base_link above the ground, m: r - wheel_vertical_offset = 0.14493.
BASE_LINK_HEIGHT_M = URDF_WHEEL_RADIUS_M - URDF_WHEEL_VERTICAL_OFFSET_M
#: imu_link origin in the Husky base_link (static transform of the robot_localization test), m.
IMU_IN_HUSKY_BASE_M = (0.0, -0.3, 0.52)

#: Rotation imu_link -> base_link, ``Rz(-pi/2) Rx(pi/2)`` (yaw -pi/2, pitch 0, roll pi/2 of
#: the test's static transform): base = IMU_TO_BASE @ imu.
IMU_TO_BASE = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
#: Rolling-mean window of the controller's twist (ros_controllers default of the time), cycles.
TWIST_WINDOW = 10
#: sensor_msgs/NavSatStatus.STATUS_NO_FIX.
STATUS_NO_FIX = -1
SOURCES = ("pose", "twist")

HUSKY_VEHICLE_COMMENT = """\
Clearpath Husky A200 of robot_localization's test1.bag (skid steer, both wheels of a side
chained). base_link = centre of the rear axle on the ground (contract); the Husky's own
base_link is wheelbase / 2 = 0.256 m ahead of it and 0.14493 m above the ground.
Sources: husky/husky husky_description/urdf/husky.urdf.xacro and wheel.urdf.xacro (commit
0cb42db), husky_control/config/control.yaml (commit ff35312), husky/husky_robot
husky_base/launch/base.launch (commit 871922d); robot_localization
test/test_ekf_localization_node_bag1.test (IMU transform).
nominal_tire_radius_m: 0.17775 = URDF wheel_radius x wheel_radius_multiplier 1.0 (also the
  driver's wheel_diameter 0.3555 / 2): the radius the odometry speed was computed with, not a
  measured rolling radius (the outdoor tyre is 13 in, r = 0.1651 m).
track_width_m: 1.07025 = wheel_separation_multiplier 1.875 x URDF track 0.5708 m, the
  EFFECTIVE skid-steer separation the controller's yaw rate was computed with (the wheel
  centres are 0.5708 m apart).
wheelbase_m: 0.512 (URDF, physical).
cg_to_front_axle_m / cg_to_rear_axle_m / cg_height_m: centre of mass of the URDF chassis
  (33.455 kg at x = -0.08748 m, z = 0.09947 m from the Husky base_link) and four wheels of
  2.637 kg (at x = +-0.256 m, z = 0.03282 m); payload (sensors, computer) unknown.
mass_kg: 33.455 + 4 x 2.637 = 44.0 kg (URDF, without payload).
yaw_inertia_kg_m2: URDF chassis izz 2.0296 kg m^2 moved to the common centre plus the wheels
  (point masses at the wheel centres plus ixx 0.02467 kg m^2 each).
drive: all (four driven wheels, two chained per side).
gnss_antenna_position_m: UNKNOWN (no transform for the /gps frame in the data or the test),
  written as (0, 0, 0).
imu_position_m: (0.256, -0.3, 0.665): the test's static transform (0, -0.3, 0.52) from the
  Husky base_link, moved to the contract base_link.
steering_ratio, cornering / longitudinal stiffness: project defaults, not measured; with
  drive: all the longitudinal ones and mass_kg set the slip prior of the rear wheels
  (0.002 % at this mass), otherwise unused by a skid steer without steering.
"""


@dataclass(frozen=True)
class HuskyOptions:
    """Choices of the conversion (defaults: the Husky software of the recording).

    Attributes:
        source: ``pose`` (per-cycle increments of the odometry pose, default) or ``twist``
            (the controller's published twist, a 1 s rolling mean).
        nominal_radius_m: radius the side speeds are divided by, m.
        effective_separation_m: ``b_eff`` of the side speeds, m.
    """

    source: str = "pose"
    nominal_radius_m: float = NOMINAL_WHEEL_RADIUS_M
    effective_separation_m: float = EFFECTIVE_SEPARATION_M

    def __post_init__(self) -> None:
        if self.source not in SOURCES:
            raise ConfigError("husky.source", self.source, f"must be one of {SOURCES}")
        for name in ("nominal_radius_m", "effective_separation_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ConfigError(f"husky.{name}", value, "must be a positive number")


def husky_vehicle(options: HuskyOptions | None = None) -> VehicleParams:
    """The Husky of the recording (numbers and sources in :data:`HUSKY_VEHICLE_COMMENT`).

    Centre of mass of chassis + wheels: ``x_c = m_c x_ch / (m_c + 4 m_w)`` (the wheels are
    symmetric about the Husky base_link), likewise z; yaw inertia about it
    ``I = izz + m_c |p_ch - p|^2 + sum_w (m_w |p_w - p|^2 + ixx_w)`` in the horizontal plane.
    """
    opts = options or HuskyOptions()
    m_c, m_w = URDF_CHASSIS_MASS_KG, URDF_WHEEL_MASS_KG
    mass = m_c + 4.0 * m_w
    cx, cy, cz = URDF_CHASSIS_CENTRE_M
    x_cg = m_c * cx / mass
    z_cg = (m_c * cz + 4.0 * m_w * URDF_WHEEL_VERTICAL_OFFSET_M) / mass
    half_l, half_t = 0.5 * URDF_WHEELBASE_M, 0.5 * URDF_TRACK_M
    wheels_xy = [(sx * half_l, sy * half_t) for sx in (1.0, -1.0) for sy in (1.0, -1.0)]
    inertia = URDF_CHASSIS_IZZ_KG_M2 + m_c * ((cx - x_cg) ** 2 + cy**2)
    for wx, wy in wheels_xy:
        inertia += m_w * ((wx - x_cg) ** 2 + wy**2) + URDF_WHEEL_DIAMETRAL_INERTIA_KG_M2
    lf = round(half_l - x_cg, 4)
    ix, iy, iz = IMU_IN_HUSKY_BASE_M
    return VehicleParams(
        name="clearpath_husky_robot_localization_test1",
        nominal_tire_radius_m=opts.nominal_radius_m,
        track_width_m=round(opts.effective_separation_m, 5),
        wheelbase_m=URDF_WHEELBASE_M,
        cg_to_front_axle_m=lf,
        cg_to_rear_axle_m=round(URDF_WHEELBASE_M - lf, 4),
        cg_height_m=round(BASE_LINK_HEIGHT_M + z_cg, 4),
        mass_kg=round(mass, 3),
        yaw_inertia_kg_m2=round(inertia, 3),
        drive="all",
        gnss_antenna_position_m=(0.0, 0.0, 0.0),
        imu_position_m=(half_l + ix, iy, round(BASE_LINK_HEIGHT_M + iz, 5)),
    )


@dataclass(frozen=True)
class HuskyRecording:
    """The arrays of the bag the converter uses (stamps = header stamps, ns, increasing).

    ``odom_position_m`` (M, 2) and ``odom_yaw_rad`` (M,) (unwrapped) in the ``odom`` frame;
    ``odom_linear_m_s`` / ``odom_angular_rad_s`` (M, 3) the twist in the child frame;
    ``imu_*`` (M, 3) in imu_link axes; ``fix_cov_m2`` (M, 9) ENU, row-major.
    """

    path: Path
    frame_ids: dict[str, list[str]]
    odom_t_ns: I64
    odom_position_m: F64
    odom_yaw_rad: F64
    odom_linear_m_s: F64
    odom_angular_rad_s: F64
    imu_t_ns: I64
    imu_gyro_rad_s: F64
    imu_accel_m_s2: F64
    fix_t_ns: I64
    fix_lat_deg: F64
    fix_lon_deg: F64
    fix_alt_m: F64
    fix_cov_m2: F64
    fix_cov_type: NDArray[np.int64]
    fix_status: NDArray[np.int64]
    dropped: dict[str, int]


def _bag_path(data: Path) -> Path:
    if data.is_file():
        return data
    if not data.is_dir():
        raise ConvertError(f"{WHAT}: missing folder {data}")
    path = data / BAG_FILE
    if not path.is_file():
        raise ConvertError(f"{WHAT}: missing file {path}")
    return path


def _stamp_ns(msg: Any) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def _vec(v: Any) -> tuple[float, float, float]:
    return (float(v.x), float(v.y), float(v.z))


def _odom_row(msg: Any) -> list[float]:
    q = msg.pose.pose.orientation
    # heading of a planar pose: yaw = atan2(2 (w z + x y), 1 - 2 (y^2 + z^2))
    yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
    p = msg.pose.pose.position
    tw = msg.twist.twist
    return [float(p.x), float(p.y), yaw, *_vec(tw.linear), *_vec(tw.angular)]


def _imu_row(msg: Any) -> list[float]:
    return [*_vec(msg.angular_velocity), *_vec(msg.linear_acceleration)]


def _fix_row(msg: Any) -> list[float]:
    return [
        float(msg.latitude),
        float(msg.longitude),
        float(msg.altitude),
        *[float(c) for c in msg.position_covariance],
        float(msg.position_covariance_type),
        float(msg.status.status),
    ]


_ROWS: dict[str, Callable[[Any], list[float]]] = {
    ODOM_TOPIC: _odom_row,
    IMU_TOPIC: _imu_row,
    FIX_TOPIC: _fix_row,
}


def _read_topics(path: Path) -> tuple[dict[str, tuple[I64, F64]], dict[str, list[str]]]:
    """(stamps, rows) per topic of :data:`_ROWS` and the frame ids seen on each."""
    from rosbags.rosbag1 import Reader
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    stamps: dict[str, list[int]] = {k: [] for k in _ROWS}
    rows: dict[str, list[list[float]]] = {k: [] for k in _ROWS}
    frames: dict[str, set[str]] = {k: set() for k in _ROWS}
    try:
        with Reader(path) as reader:
            conns = [c for c in reader.connections if c.topic in _ROWS]
            for topic, msgtype in _TYPES.items():
                found = [c for c in conns if c.topic == topic]
                if not found:
                    raise ConvertError(f"{WHAT}: {path} has no topic {topic}")
                for conn in found:
                    if conn.msgtype != msgtype:
                        raise ConvertError(f"{WHAT}: {topic} is {conn.msgtype}, not {msgtype}")
                    if conn.digest != store.generate_msgdef(msgtype)[1]:
                        raise ConvertError(f"{WHAT}: {topic} has an unknown {msgtype} layout")
            for conn, _, raw in reader.messages(connections=conns):
                msg = store.deserialize_ros1(raw, conn.msgtype)
                stamps[conn.topic].append(_stamp_ns(msg))
                rows[conn.topic].append(_ROWS[conn.topic](msg))
                frame = msg.header.frame_id
                if conn.topic == ODOM_TOPIC:
                    frame = f"{frame} -> {msg.child_frame_id}"
                frames[conn.topic].add(frame)
    except ConvertError:
        raise
    except Exception as exc:  # rosbags raises its own error types for corrupt bags
        raise ConvertError(f"{WHAT}: cannot read {path}: {exc}") from exc
    out: dict[str, tuple[I64, F64]] = {}
    for topic in _ROWS:
        if not stamps[topic]:
            raise ConvertError(f"{WHAT}: {topic} has no messages")
        out[topic] = (np.asarray(stamps[topic], dtype=np.int64), np.asarray(rows[topic]))
    return out, {k: sorted(v) for k, v in frames.items()}


def load_husky(data_dir: Path | str) -> HuskyRecording:
    """Read the topics the converter needs; :class:`ConvertError` names what is missing.

    Messages are sorted by header stamp; a message whose stamp is not after the previous one
    is dropped (counted in ``dropped``).
    """
    path = _bag_path(Path(data_dir))
    data, frames = _read_topics(path)
    dropped: dict[str, int] = {}
    kept: dict[str, tuple[I64, F64]] = {}
    for topic, (t_ns, rows) in data.items():
        order = np.argsort(t_ns, kind="stable")
        t_sorted, r_sorted = t_ns[order], rows[order]
        keep = increasing_rows(t_sorted)
        dropped[topic] = int(len(t_ns) - len(keep))
        kept[topic] = (t_sorted[keep], r_sorted[keep])
    t_o, odom = kept[ODOM_TOPIC]
    if len(t_o) < 2:
        raise ConvertError(f"{WHAT}: {ODOM_TOPIC} has fewer than 2 messages")
    t_i, imu = kept[IMU_TOPIC]
    t_f, fix = kept[FIX_TOPIC]
    return HuskyRecording(
        path=path,
        frame_ids=frames,
        odom_t_ns=t_o,
        odom_position_m=odom[:, 0:2],
        odom_yaw_rad=np.unwrap(odom[:, 2]),
        odom_linear_m_s=odom[:, 3:6],
        odom_angular_rad_s=odom[:, 6:9],
        imu_t_ns=t_i,
        imu_gyro_rad_s=imu[:, 0:3],
        imu_accel_m_s2=imu[:, 3:6],
        fix_t_ns=t_f,
        fix_lat_deg=fix[:, 0],
        fix_lon_deg=fix[:, 1],
        fix_alt_m=fix[:, 2],
        fix_cov_m2=fix[:, 3:12],
        fix_cov_type=fix[:, 12].astype(np.int64),
        fix_status=fix[:, 13].astype(np.int64),
        dropped=dropped,
    )


def pose_increment_velocities(t_ns: I64, position_m: F64, yaw_rad: F64) -> tuple[I64, F64, F64]:
    """Per-cycle speed and yaw rate from consecutive planar poses of a diff-drive odometry.

    ``dpsi = psi_k - psi_{k-1}``; the controller moves each cycle along an arc, whose chord
    points along the mid heading ``psi_{k-1} + dpsi / 2`` and is ``sinc(dpsi / 2)`` times the
    arc length: ``ds = (dx cos psi_m + dy sin psi_m) / sinc(dpsi / 2)``. Returns the stamps of
    the cycle middles ``(t_{k-1} + t_k) / 2`` (ns), ``ds / dt`` (m/s) and ``dpsi / dt``
    (rad/s), each (M - 1,).
    """
    dt_ns = np.diff(t_ns)
    dt_s = dt_ns * 1e-9
    dpsi = np.diff(yaw_rad)
    mid = yaw_rad[:-1] + 0.5 * dpsi
    d = np.diff(position_m, axis=0)
    chord = d[:, 0] * np.cos(mid) + d[:, 1] * np.sin(mid)
    # np.sinc(x) = sin(pi x) / (pi x): sinc(dpsi / 2) = np.sinc(dpsi / (2 pi))
    arc = chord / np.sinc(dpsi / (2.0 * math.pi))
    t_mid = t_ns[:-1] + dt_ns // 2
    return t_mid, arc / dt_s, dpsi / dt_s


def side_speeds_m_s(speed_m_s: F64, yaw_rate_rad_s: F64, separation_m: float) -> tuple[F64, F64]:
    """Left and right surface speeds of a differential drive: ``v -+ w b / 2`` (inverse of
    ``v = (v_l + v_r) / 2``, ``w = (v_r - v_l) / b``)."""
    half = 0.5 * separation_m * np.asarray(yaw_rate_rad_s, dtype=np.float64)
    v = np.asarray(speed_m_s, dtype=np.float64)
    return v - half, v + half


def wheel_speeds_rad_s(left_m_s: F64, right_m_s: F64, radius_m: float) -> F64:
    """(M, 4) angular speeds in the order of ``WHEELS`` (fl, fr, rl, rr): ``v_side / r``, the
    left side on fl and rl, the right side on fr and rr (chained wheels)."""
    left = np.asarray(left_m_s, dtype=np.float64) / radius_m
    right = np.asarray(right_m_s, dtype=np.float64) / radius_m
    return np.column_stack([left, right, left, right])


def imu_to_base(vectors: F64) -> F64:
    """(M, 3) imu_link vectors in base_link axes (``IMU_TO_BASE @ v`` per row)."""
    return np.asarray(np.asarray(vectors, dtype=np.float64) @ IMU_TO_BASE.T)


def husky_series(
    rec: HuskyRecording, options: HuskyOptions | None = None
) -> tuple[list[TopicSeries], dict[str, Any]]:
    """Contract topic series of the recording and a record of the conversion."""
    opts = options or HuskyOptions()
    if opts.source == "pose":
        t_w, v, w = pose_increment_velocities(rec.odom_t_ns, rec.odom_position_m, rec.odom_yaw_rad)
    else:
        t_w, v, w = rec.odom_t_ns, rec.odom_linear_m_s[:, 0], rec.odom_angular_rad_s[:, 2]
    left, right = side_speeds_m_s(v, w, opts.effective_separation_m)
    omega = wheel_speeds_rad_s(left, right, opts.nominal_radius_m)
    series: list[TopicSeries] = [joint_series(tp.WHEEL_SPEEDS, t_w, WHEELS, "velocity", omega)]

    gyro = imu_to_base(rec.imu_gyro_rad_s)
    accel = imu_to_base(rec.imu_accel_m_s2)
    gyro_std = float(np.mean(diff_noise_std(gyro)))
    accel_std = float(np.mean(diff_noise_std(accel)))
    imu = ImuStream(
        rec.imu_t_ns, gyro, accel, gyro_noise_std_rad_s=gyro_std, accel_noise_std_m_s2=accel_std
    )
    series.append(imu_series(imu))

    ok = (rec.fix_status > STATUS_NO_FIX) & np.all(
        np.isfinite(np.column_stack([rec.fix_lat_deg, rec.fix_lon_deg, rec.fix_alt_m])), axis=1
    )
    if not np.any(ok):
        raise ConvertError(f"{WHAT}: {FIX_TOPIC} has no usable fix")
    cov_types = np.unique(rec.fix_cov_type[ok])
    cov = np.where(rec.fix_cov_type[ok, None] > 0, rec.fix_cov_m2[ok], 0.0).reshape(-1, 3, 3)
    series.append(
        fix_series(
            tp.GNSS_FIX,
            rec.fix_t_ns[ok],
            rec.fix_lat_deg[ok],
            rec.fix_lon_deg[ok],
            rec.fix_alt_m[ok],
            cov,
            tp.GNSS_FRAME,
            covariance_type=int(cov_types.max()),
        )
    )
    info: dict[str, Any] = {
        "source": "husky robot_localization test1.bag",
        "bag": rec.path.name,
        "clock": "ROS 1 header stamps (s, ns) -> ns",
        "options": dataclasses.asdict(opts),
        "frame_ids": rec.frame_ids,
        "imu_to_base_link": IMU_TO_BASE.tolist(),
        "imu_noise_std": {"gyro_rad_s": gyro_std, "accel_m_s2": accel_std},
        "gnss_covariance_types": [int(c) for c in cov_types],
        "dropped_rows": {**rec.dropped, "fix_without_fix_or_finite_position": int(np.sum(~ok))},
        "checks": _checks(rec, opts),
    }
    return series, info


def _fit_gain(x: F64, y: F64) -> tuple[float, float]:
    """Least-squares gain of ``y = k x + c`` and the correlation of x and y."""
    a = np.column_stack([x, np.ones_like(x)])
    k = float(np.linalg.lstsq(a, y, rcond=None)[0][0])
    corr = float(np.corrcoef(x, y)[0, 1]) if np.std(x) > 0 and np.std(y) > 0 else math.nan
    return k, corr


def _box_mean(x: F64, n: int) -> F64:
    """Centred moving mean over ``n`` samples, over the samples that exist at the ends."""
    ones = np.ones(n)
    return np.asarray(
        np.convolve(x, ones, mode="same") / np.convolve(np.ones_like(x), ones, mode="same")
    )


def _checks(rec: HuskyRecording, opts: HuskyOptions) -> dict[str, Any]:
    """Numbers measured on the recording at conversion time (for conversion.yaml)."""
    t_o = rec.odom_t_ns
    t_mid, v_inc, w_inc = pose_increment_velocities(t_o, rec.odom_position_m, rec.odom_yaw_rad)
    ds = v_inc * np.diff(t_o) * 1e-9
    dpsi = np.diff(rec.odom_yaw_rad)
    left_mm = (ds - 0.5 * opts.effective_separation_m * dpsi) * 1e3
    whole_mm = float(np.mean(np.abs(left_mm - np.rint(left_mm)) < 0.01))
    v_tw, w_tw = rec.odom_linear_m_s[:, 0], rec.odom_angular_rad_s[:, 2]
    window = np.ones(TWIST_WINDOW) / TWIST_WINDOW
    roll_v = np.convolve(v_inc, window, mode="valid")
    roll_w = np.convolve(w_inc, window, mode="valid")
    twist_vs_roll = {
        "speed_rms_m_s": float(np.sqrt(np.mean((v_tw[TWIST_WINDOW:] - roll_v) ** 2))),
        "yaw_rate_rms_rad_s": float(np.sqrt(np.mean((w_tw[TWIST_WINDOW:] - roll_w) ** 2))),
    }
    t_s = (t_o - t_o[0]) * 1e-9
    t_i = (rec.imu_t_ns - t_o[0]) * 1e-9
    gyro = imu_to_base(rec.imu_gyro_rad_s)
    accel = imu_to_base(rec.imu_accel_m_s2)
    # accelerations averaged over 1 s (the twist's window) for the sign checks
    kernel = max(1, round(1.0 / float(np.median(np.diff(t_i)))))
    acc_s = np.column_stack([_box_mean(accel[:, k], kernel) for k in range(3)])
    acc_o = np.column_stack([np.interp(t_s, t_i, acc_s[:, k]) for k in range(3)])
    gz_o = np.interp(t_s, t_i, gyro[:, 2])
    dvdt = _box_mean(np.gradient(v_tw, t_s), 5)
    stand = np.abs(v_tw) < 0.01
    gain_gz, corr_gz = _fit_gain(w_tw, gz_o)
    gain_ay, corr_ay = _fit_gain(v_tw * w_tw, acc_o[:, 1])
    gain_ax, corr_ax = _fit_gain(dvdt, acc_o[:, 0])
    heading_gyro = float(np.sum(0.5 * (gyro[1:, 2] + gyro[:-1, 2]) * np.diff(t_i)))
    cov = rec.fix_cov_m2
    return {
        "odometry_twist_nonzero_components": {
            "max_abs_linear_y_z_m_s": float(np.max(np.abs(rec.odom_linear_m_s[:, 1:]))),
            "max_abs_angular_x_y_rad_s": float(np.max(np.abs(rec.odom_angular_rad_s[:, :2]))),
        },
        "twist_minus_10_cycle_mean_of_pose_increments": twist_vs_roll,
        "side_travel_whole_mm_fraction": whole_mm,
        "distance_m": float(np.sum(np.abs(ds))),
        "duration_s": float(t_s[-1]),
        "max_speed_m_s": float(np.max(v_inc)),
        "odometry_heading_change_deg": math.degrees(
            float(rec.odom_yaw_rad[-1] - rec.odom_yaw_rad[0])
        ),
        "gyro_heading_change_deg": math.degrees(heading_gyro),
        "gyro_z_vs_odometry_yaw_rate": {"gain": gain_gz, "corr": corr_gz},
        "accel_y_vs_speed_times_yaw_rate": {"gain": gain_ay, "corr": corr_ay},
        "accel_x_vs_speed_derivative": {"gain": gain_ax, "corr": corr_ax},
        "standstill_samples": int(np.sum(stand)),
        "accel_at_standstill_m_s2": (
            [float(a) for a in acc_o[stand].mean(axis=0)] if np.any(stand) else None
        ),
        "gnss_horizontal_std_m": [
            float(np.sqrt(cov[:, 0].min())),
            float(np.sqrt(np.median(cov[:, 0]))),
            float(np.sqrt(cov[:, 0].max())),
        ],
        "gnss_status": sorted({int(s) for s in rec.fix_status}),
        "gnss_altitude_range_m": [float(rec.fix_alt_m.min()), float(rec.fix_alt_m.max())],
        "wheel_speed_stamps": "cycle middles" if opts.source == "pose" else "message stamps",
        "wheel_speed_samples": int(len(t_mid) if opts.source == "pose" else len(t_o)),
    }


def _attribution(command: str | None) -> str:
    cmd = command or "tire-estimation convert husky DATA_DIR --out BAG"
    return attribution(
        """\
Converted from `test/test1.bag` of cra-ros-pkg/robot_localization (Charles River Analytics,
2014; BSD licence, see `SOURCE_README.md` when present): a Clearpath Husky driven around a
parking lot with a Microstrain 3DM-GX2 IMU and a GPS receiver.

The measurements were converted to the tire_estimation contract (side wheel speeds from the
drive controller's odometry, IMU rotated into base_link, GNSS copied); see `conversion.yaml`,
`vehicle.yaml` and `docs/data_husky.md` of the project.""",
        cmd,
    )


def convert_husky(
    data_dir: Path | str,
    out_dir: Path | str,
    *,
    overwrite: bool = False,
    options: HuskyOptions | None = None,
    command: str | None = None,
) -> Path:
    """Convert the Husky bag in ``data_dir`` (or the bag file itself) to a contract bag.

    The bag holds ``/vehicle/wheel_speeds``, ``/imu/data``, ``/gnss/fix``, ``vehicle.yaml``,
    ``conversion.yaml`` (choices, frames, checks), ``ATTRIBUTION.md`` and the source's
    ``README.md`` (with its licence) as ``SOURCE_README.md`` when found next to the bag.

    Raises:
        ConvertError: the bag or a topic is missing, unreadable or unusable.
        BagError: ``out_dir`` exists (without ``overwrite``) or cannot be written.
    """
    opts = options or HuskyOptions()
    rec = load_husky(data_dir)
    series, info = husky_series(rec, opts)
    vehicle = husky_vehicle(opts)
    return write_converted_bag(
        out_dir,
        vehicle,
        series,
        info,
        source=f"husky robot_localization {rec.path.name}",
        conversion_keys=("clock", "options", "imu_to_base_link"),
        attribution_md=_attribution(command),
        vehicle_comment=HUSKY_VEHICLE_COMMENT,
        source_files={"SOURCE_README.md": rec.path.parent / "README.md"},
        overwrite=overwrite,
    )


__all__ = [
    "EFFECTIVE_SEPARATION_M",
    "IMU_TO_BASE",
    "NOMINAL_WHEEL_RADIUS_M",
    "HuskyOptions",
    "HuskyRecording",
    "convert_husky",
    "husky_series",
    "husky_vehicle",
    "imu_to_base",
    "load_husky",
    "pose_increment_velocities",
    "side_speeds_m_s",
    "wheel_speeds_rad_s",
]
