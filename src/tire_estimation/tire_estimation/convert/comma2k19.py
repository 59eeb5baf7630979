"""comma2k19 segment (2018 Toyota RAV4, comma EON device) -> contract bag.

Input layout (one segment folder, every signal a folder with NumPy arrays ``t`` and ``value``
stored without extension, ``t`` in seconds of the device boot clock shared by all signals)::

    processed_log/CAN/wheel_speed      (N, 4) m/s, fl fr rl rr, from the car's own radius
    processed_log/CAN/steering_angle   (N,)   deg at the steering wheel, positive to the left
    processed_log/IMU/accelerometer    (N, 3) m/s^2 specific force, device [forward, right, down]
    processed_log/IMU/gyro             (N, 3) rad/s, device [forward, right, down]
    processed_log/GNSS/live_gnss_ublox (N, 6) lat deg, lon deg, speed m/s, UTC ms, alt m,
                                              bearing deg (clockwise from north)
    global_pose/frame_times, frame_positions (ECEF m), frame_velocities (ECEF m/s),
                frame_orientations (Hamilton quaternion w, x, y, z: device -> ECEF)

Conversion (checked on the real segment, see ``docs/data_comma2k19.md``):

* header stamps = device boot clock ``t`` in ns (no shift to UTC; every topic, including
  the reference, uses the same clock). GNSS fixes keep their arrival time ``t``.
* ``/vehicle/wheel_speeds``: ``value / nominal_tire_radius_m`` rad/s (the car's own radius
  is not published; the RAV4 nominal radius of :data:`RAV4_NOMINAL_RADIUS_M` is assumed).
* ``/vehicle/steering``: ``radians(steering_angle) / steering_ratio`` (CAN sign is already
  positive to the left: it correlates +0.90 with the yaw rate).
* ``/imu/data``: device [forward, right, down] -> base_link [forward, left, up] by
  ``diag(1, -1, -1)`` followed by a constant mounting rotation (yaw and pitch of the device
  relative to the vehicle, roll assumed zero) estimated from the reference velocity direction
  in the device frame while driving; the accelerometer is a specific force (z = -9.7 at rest
  in the device frame), so base_link z is about +9.7.
* ``/gnss/fix`` (frame ``gnss_antenna``, diagonal ENU covariance from assumed std) and
  ``/gnss/velocity`` (ENU from speed and bearing; up not measured).
* ``/reference/odometry``: ``global_pose`` moved from the device to ``base_link`` with the
  mounting rotation and the lever arm ``device_position_m``; pose in ``map`` ENU with its
  origin at the first reference position of base_link (stored in the metadata custom data
  and in ``conversion.yaml``), twist of base_link in base_link axes, angular rate from the
  reference orientations (independent of the IMU).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pymap3d
import yaml
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from tire_estimation.bag import topics as tp
from tire_estimation.bag.writer import (
    CUSTOM_ORIGIN,
    TopicSeries,
    fix_series,
    imu_series,
    joint_series,
    odometry_series,
    velocity_series,
)
from tire_estimation.convert.common import (
    CUSTOM_REFERENCE_ORIGIN,
    UNMEASURED_VELOCITY_VARIANCE,
    ConvertError,
    attribution,
    body_rates,
    diff_noise_std,
    increasing_rows,
    load_npy,
    matrices_to_quaternions_xyzw,
    require_dir,
    seconds_to_ns,
    write_converted_bag,
)
from tire_estimation.core.arrays import F64, I64
from tire_estimation.core.geodesy import LocalTangentPlane
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.core.wheels import WHEELS
from tire_estimation.sim.streams import ImuStream

WHAT = "comma2k19 segment"


def tire_radius_m(width_mm: float, aspect_pct: float, rim_in: float) -> tuple[float, float]:
    """(unloaded radius, nominal rolling radius) in m of an ISO metric tyre size.

    Unloaded diameter ``D = rim + 2 * width * aspect``; the rolling radius uses the ETRTO
    rule for passenger-car radial tyres, dynamic rolling circumference = 3.05 * D.
    """
    diameter_m = rim_in * 0.0254 + 2.0 * width_mm * 1e-3 * aspect_pct * 1e-2
    return 0.5 * diameter_m, 3.05 * diameter_m / (2.0 * math.pi)


#: 2018 RAV4 LE/XLE tyre 225/65R17: D = 0.7243 m, unloaded 0.3622 m, rolling 0.3516 m.
RAV4_UNLOADED_RADIUS_M, RAV4_NOMINAL_RADIUS_M = tire_radius_m(225.0, 65.0, 17.0)

RAV4_VEHICLE_COMMENT = """\
2018 Toyota RAV4 (4th generation, XA40) of the comma2k19 dataset. Sources / derivations:
name: free text.
nominal_tire_radius_m: tyre 225/65R17 (RAV4 LE/XLE): unloaded diameter 17 in + 2 x 225 mm x
  0.65 = 0.7243 m (radius 0.3622 m); rolling radius by the ETRTO rule (dynamic rolling
  circumference = 3.05 x diameter) = 0.3516 m. The car's own CAN radius is unknown: the
  converter divides the CAN wheel speeds (m/s) by this radius.
track_width_m: 61.4 in front and rear (4th-gen RAV4 spec sheet) = 1.560 m.
wheelbase_m: 104.7 in = 2.659 m (spec sheet; openpilot uses 2.65 m).
cg_to_front_axle_m / cg_to_rear_axle_m: ESTIMATE, 58 % of the weight on the front axle
  (typical of a transverse-engine crossover): lf = 0.42 L, lr = 0.58 L.
cg_height_m: ESTIMATE, 0.65 m (about 0.38 x the 1.70 m overall height).
mass_kg: ESTIMATE, 3,610 lb curb weight (1,637 kg, AWD, spec sheet) + driver and device
  (about 75 kg); the trim of the recorded car is unknown (FWD 1,560 kg ... AWD 1,640 kg).
yaw_inertia_kg_m2: ESTIMATE, m (length^2 + width^2) / 12 with 4.570 m x 1.845 m, +-20 %.
drive: front (FWD, or the front-biased on-demand AWD of this generation).
gnss_antenna_position_m / imu_position_m: the comma EON (camera, IMU and u-blox antenna in
  one device) at the windshield behind the rear-view mirror: x = 1.45 m ESTIMATE (about
  1.2 m behind the front axle, +-0.2 m), y = +0.06 m (openpilot CAMERA_OFFSET for the EON:
  camera 6 cm left of the car centre), z = 1.22 m (openpilot model_height, camera height
  above the road). The segment's small yaw rates cannot calibrate x (fit: 0.1 m, unusable).
steering_ratio: 14.5, the end-to-end spec ratio quoted in openpilot's Toyota interface
  (openpilot uses a learned effective 16.88; lock to lock 2.68 turns). Steering-wheel
  angle / 14.5 = mean road-wheel angle.
cornering / longitudinal stiffness: project defaults, not RAV4 measurements.
"""


@dataclass(frozen=True)
class Comma2k19Options:
    """Numbers the conversion assumes (defaults: the 2018 RAV4 of the public dataset)."""

    nominal_tire_radius_m: float = RAV4_NOMINAL_RADIUS_M
    steering_ratio: float = 14.5
    #: Device (camera, IMU, GNSS antenna) position in base_link, m.
    device_position_m: tuple[float, float, float] = (1.45, 0.06, 1.22)
    #: Assumed 1-sigma u-blox position noise (the log has no accuracy column), m.
    gnss_horizontal_std_m: float = 1.5
    gnss_vertical_std_m: float = 3.0
    #: Assumed 1-sigma noise of each horizontal component of the u-blox velocity, m/s.
    gnss_velocity_std_m_s: float = 0.1
    #: Below this u-blox speed the bearing is meaningless; no /gnss/velocity is written, m/s.
    min_bearing_speed_m_s: float = 0.5
    #: Reference samples used to estimate the device mounting rotation (speed above), m/s.
    align_min_speed_m_s: float = 5.0


def rav4_vehicle(options: Comma2k19Options | None = None) -> VehicleParams:
    """The 2018 Toyota RAV4 (numbers and sources in :data:`RAV4_VEHICLE_COMMENT`)."""
    opts = options or Comma2k19Options()
    wheelbase = 2.659
    return VehicleParams(
        name="toyota_rav4_2018_comma2k19",
        nominal_tire_radius_m=round(opts.nominal_tire_radius_m, 4),
        track_width_m=1.560,
        wheelbase_m=wheelbase,
        cg_to_front_axle_m=round(0.42 * wheelbase, 3),
        cg_to_rear_axle_m=round(wheelbase - round(0.42 * wheelbase, 3), 3),
        cg_height_m=0.65,
        mass_kg=1710.0,
        yaw_inertia_kg_m2=round(1710.0 * (4.570**2 + 1.845**2) / 12.0, -1),
        drive="front",
        gnss_antenna_position_m=tuple(opts.device_position_m),
        imu_position_m=tuple(opts.device_position_m),
        steering_ratio=opts.steering_ratio,
    )


@dataclass(frozen=True)
class Comma2k19Segment:
    """The raw arrays of one segment (times in s of the device boot clock)."""

    path: Path
    wheel_t: F64
    wheel_speed_m_s: F64  # (N, 4) fl fr rl rr
    steer_t: F64
    steer_deg: F64
    accel_t: F64
    accel_frd: F64
    gyro_t: F64
    gyro_frd: F64
    gnss_t: F64
    gnss: F64  # (N, 6) lat, lon, speed, utc ms, alt, bearing
    pose_t: F64
    pose_ecef_m: F64
    pose_vel_ecef_m_s: F64
    pose_quat_wxyz: F64


def _signal(root: Path, folder: str, columns: int | None) -> tuple[F64, F64]:
    t = np.asarray(load_npy(root / folder / "t", WHAT), dtype=np.float64).reshape(-1)
    value = np.asarray(load_npy(root / folder / "value", WHAT), dtype=np.float64)
    if columns is None:
        value = value.reshape(-1)
    elif value.ndim != 2 or value.shape[1] != columns:
        raise ConvertError(
            f"{WHAT}: {folder}/value has shape {value.shape}, expected (N, {columns})"
        )
    if value.shape[0] != t.shape[0]:
        raise ConvertError(f"{WHAT}: {folder} has {t.shape[0]} times but {value.shape[0]} values")
    if t.size == 0:
        raise ConvertError(f"{WHAT}: {folder} is empty")
    return t, value


def _pose(root: Path, name: str, columns: int | None) -> F64:
    arr = np.asarray(load_npy(root / "global_pose" / name, WHAT), dtype=np.float64)
    if columns is not None and (arr.ndim != 2 or arr.shape[1] != columns):
        raise ConvertError(f"{WHAT}: global_pose/{name} has shape {arr.shape}")
    return arr if columns is not None else arr.reshape(-1)


def load_segment(segment_dir: Path | str) -> Comma2k19Segment:
    """Read the arrays the converter needs; :class:`ConvertError` names what is missing."""
    root = require_dir(Path(segment_dir), WHAT)
    wheel_t, wheel = _signal(root, "processed_log/CAN/wheel_speed", 4)
    steer_t, steer = _signal(root, "processed_log/CAN/steering_angle", None)
    accel_t, accel = _signal(root, "processed_log/IMU/accelerometer", 3)
    gyro_t, gyro = _signal(root, "processed_log/IMU/gyro", 3)
    gnss_t, gnss = _signal(root, "processed_log/GNSS/live_gnss_ublox", 6)
    pose_t = _pose(root, "frame_times", None)
    pos = _pose(root, "frame_positions", 3)
    vel = _pose(root, "frame_velocities", 3)
    quat = _pose(root, "frame_orientations", 4)
    if not len(pose_t) == len(pos) == len(vel) == len(quat) or len(pose_t) < 2:
        raise ConvertError(f"{WHAT}: global_pose arrays have different or too few rows")
    return Comma2k19Segment(
        root,
        wheel_t,
        wheel,
        steer_t,
        steer,
        accel_t,
        accel,
        gyro_t,
        gyro,
        gnss_t,
        gnss,
        pose_t,
        pos,
        vel,
        quat,
    )


#: Device [forward, right, down] -> device [forward, left, up].
FRD_TO_FLU = np.diag([1.0, -1.0, -1.0])


def device_rotations(seg: Comma2k19Segment) -> F64:
    """(M, 3, 3) rotation device (FRD) -> ECEF of every reference frame."""
    q = seg.pose_quat_wxyz
    return np.asarray(Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix(), dtype=np.float64)


def mount_rotation(seg: Comma2k19Segment, min_speed_m_s: float) -> tuple[F64, float, float]:
    """Rotation device FRD -> base_link and the mounting (yaw, pitch) in deg.

    The vehicle x axis is the mean direction of the reference velocity in the device frame
    while faster than ``min_speed_m_s`` (no sideslip or vertical velocity on average); roll is
    assumed zero (the device roll relative to level includes the unknown road crossfall).
    ``yaw`` > 0: the device x axis points left of the vehicle x axis; ``pitch`` > 0: the
    device x axis points below the vehicle x axis.
    """
    r_ecef_dev = device_rotations(seg)
    v_dev = np.einsum("nji,nj->ni", r_ecef_dev, seg.pose_vel_ecef_m_s) @ FRD_TO_FLU.T
    speed = np.linalg.norm(v_dev, axis=1)
    moving = speed > min_speed_m_s
    if np.count_nonzero(moving) < 10:
        raise ConvertError(
            f"{WHAT}: fewer than 10 reference samples faster than {min_speed_m_s} m/s; "
            "cannot estimate the device mounting"
        )
    x_axis = np.mean(v_dev[moving] / speed[moving, None], axis=0)
    x_axis /= np.linalg.norm(x_axis)
    up = np.array([0.0, 0.0, 1.0])
    z_axis = up - up.dot(x_axis) * x_axis
    z_axis /= np.linalg.norm(z_axis)
    y_axis = np.cross(z_axis, x_axis)
    axes = np.column_stack([x_axis, y_axis, z_axis])  # vehicle axes in device FLU coordinates
    rot = axes.T @ FRD_TO_FLU
    yaw_deg = math.degrees(math.atan2(-x_axis[1], x_axis[0]))
    pitch_deg = math.degrees(math.atan2(x_axis[2], math.hypot(x_axis[0], x_axis[1])))
    return rot, yaw_deg, pitch_deg


@dataclass(frozen=True)
class ReferenceTrajectory:
    """base_link reference: ``position_enu_m`` (M, 3) about ``origin_lla``, orientation (M, 4)
    xyzw of base_link in ENU, ``linear_m_s``/``angular_rad_s`` (M, 3) in base_link axes."""

    t_ns: I64
    origin_lla: tuple[float, float, float]
    position_enu_m: F64
    orientation_xyzw: F64
    linear_m_s: F64
    angular_rad_s: F64
    device_enu_m: F64  # (M, 3) the device (GNSS antenna) position, ENU m


def reference_trajectory(
    seg: Comma2k19Segment, mount: F64, device_position_m: tuple[float, float, float]
) -> ReferenceTrajectory:
    """``global_pose`` (device) moved to base_link with ``mount`` and the lever arm."""
    lever = np.asarray(device_position_m, dtype=np.float64)
    r_ecef_dev = device_rotations(seg)
    r_ecef_base = r_ecef_dev @ mount.T
    base_ecef = seg.pose_ecef_m - r_ecef_base @ lever
    lat, lon, alt = pymap3d.ecef2geodetic(base_ecef[:, 0], base_ecef[:, 1], base_ecef[:, 2])
    ltp = LocalTangentPlane(float(lat[0]), float(lon[0]), float(alt[0]))
    east, north, up = ltp.to_enu(lat, lon, alt)
    dlat, dlon, dalt = pymap3d.ecef2geodetic(*seg.pose_ecef_m.T)
    device_enu = np.column_stack(ltp.to_enu(dlat, dlon, dalt))

    lat0, lon0 = math.radians(ltp.origin_lat_deg), math.radians(ltp.origin_lon_deg)
    r_enu_ecef = np.array(
        [
            [-math.sin(lon0), math.cos(lon0), 0.0],
            [-math.sin(lat0) * math.cos(lon0), -math.sin(lat0) * math.sin(lon0), math.cos(lat0)],
            [math.cos(lat0) * math.cos(lon0), math.cos(lat0) * math.sin(lon0), math.sin(lat0)],
        ]
    )
    r_enu_base = r_enu_ecef @ r_ecef_base
    omega_dev = body_rates(seg.pose_t, r_ecef_dev)
    omega_base = omega_dev @ mount.T
    v_dev_base = np.einsum("nji,nj->ni", r_ecef_base, seg.pose_vel_ecef_m_s)
    v_base = v_dev_base - np.cross(omega_base, lever)
    return ReferenceTrajectory(
        t_ns=seconds_to_ns(seg.pose_t),
        origin_lla=ltp.origin_lla,
        position_enu_m=np.column_stack([east, north, up]),
        orientation_xyzw=matrices_to_quaternions_xyzw(r_enu_base),
        linear_m_s=v_base,
        angular_rad_s=omega_base,
        device_enu_m=device_enu,
    )


def _rows(t_s: F64) -> tuple[I64, NDArray[np.intp]]:
    t_ns = seconds_to_ns(t_s)
    keep = increasing_rows(t_ns)
    return t_ns[keep], keep


def comma2k19_series(
    seg: Comma2k19Segment, options: Comma2k19Options | None = None
) -> tuple[list[TopicSeries], dict[str, Any]]:
    """Contract topic series of a segment and a record of the conversion (for conversion.yaml)."""
    opts = options or Comma2k19Options()
    series: list[TopicSeries] = []
    dropped: dict[str, int] = {}

    t_w, keep = _rows(seg.wheel_t)
    dropped["wheel_speed"] = len(seg.wheel_t) - len(keep)
    omega = seg.wheel_speed_m_s[keep] / opts.nominal_tire_radius_m
    series.append(joint_series(tp.WHEEL_SPEEDS, t_w, WHEELS, "velocity", omega))

    t_s, keep = _rows(seg.steer_t)
    dropped["steering_angle"] = len(seg.steer_t) - len(keep)
    angle = np.radians(seg.steer_deg[keep]) / opts.steering_ratio
    series.append(joint_series(tp.STEERING, t_s, ("front_wheel_angle",), "position", angle))

    mount, yaw_deg, pitch_deg = mount_rotation(seg, opts.align_min_speed_m_s)
    t_i, keep = _rows(seg.accel_t)
    dropped["imu"] = len(seg.accel_t) - len(keep)
    accel = seg.accel_frd[keep]
    if len(seg.gyro_t) == len(seg.accel_t) and np.array_equal(seg.gyro_t, seg.accel_t):
        gyro = seg.gyro_frd[keep]
    else:  # gyro on its own clock ticks: interpolate onto the accelerometer stamps
        order = np.argsort(seg.gyro_t)
        tg = seg.gyro_t[order]
        gyro = np.column_stack(
            [np.interp(seg.accel_t[keep], tg, seg.gyro_frd[order, k]) for k in range(3)]
        )
    gyro_std = float(np.mean(diff_noise_std(gyro)))
    accel_std = float(np.mean(diff_noise_std(accel)))
    imu = ImuStream(
        t_i,
        gyro @ mount.T,
        accel @ mount.T,
        gyro_noise_std_rad_s=gyro_std,
        accel_noise_std_m_s2=accel_std,
    )
    series.append(imu_series(imu))

    g = seg.gnss
    t_g, keep = _rows(seg.gnss_t)
    finite = np.all(np.isfinite(g[keep][:, [0, 1, 4]]), axis=1)
    keep = keep[finite]
    t_g = t_g[finite]
    dropped["gnss"] = len(seg.gnss_t) - len(keep)
    cov = np.zeros((len(keep), 3, 3))
    cov[:, 0, 0] = cov[:, 1, 1] = opts.gnss_horizontal_std_m**2
    cov[:, 2, 2] = opts.gnss_vertical_std_m**2
    series.append(
        fix_series(tp.GNSS_FIX, t_g, g[keep, 0], g[keep, 1], g[keep, 4], cov, tp.GNSS_FRAME)
    )
    speed, bearing = g[keep, 2], np.radians(g[keep, 5])
    vel = np.column_stack([speed * np.sin(bearing), speed * np.cos(bearing), np.zeros(len(keep))])
    vel[~(speed >= opts.min_bearing_speed_m_s)] = np.nan
    vcov = np.zeros((len(keep), 3, 3))
    vcov[:, 0, 0] = vcov[:, 1, 1] = opts.gnss_velocity_std_m_s**2
    vcov[:, 2, 2] = UNMEASURED_VELOCITY_VARIANCE
    vel_series = velocity_series(tp.GNSS_VELOCITY, t_g, vel, vcov)
    if vel_series is not None:
        series.append(vel_series)

    ref = reference_trajectory(seg, mount, opts.device_position_m)
    keep = increasing_rows(ref.t_ns)
    dropped["global_pose"] = len(ref.t_ns) - len(keep)
    series.append(
        odometry_series(
            tp.REFERENCE_ODOMETRY,
            ref.t_ns[keep],
            ref.position_enu_m[keep],
            ref.orientation_xyzw[keep],
            ref.linear_m_s[keep],
            ref.angular_rad_s[keep],
        )
    )

    checks = _checks(seg, ref)
    lat0, lon0, alt0 = ref.origin_lla
    info: dict[str, Any] = {
        "source": "comma2k19",
        "segment": seg.path.name,
        "clock": "device boot clock (s) * 1e9; GNSS fixes stamped at arrival",
        "reference_origin": {"lat_deg": lat0, "lon_deg": lon0, "alt_m": alt0},
        "options": {
            k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(opts).items()
        },
        "device_mount": {
            "yaw_deg": yaw_deg,
            "pitch_deg": pitch_deg,
            "roll_deg": 0.0,
            "device_frd_to_base_link": mount.tolist(),
        },
        "imu_noise_std": {"gyro_rad_s": gyro_std, "accel_m_s2": accel_std},
        "dropped_rows": dropped,
        "checks": checks,
    }
    return series, info


def _checks(seg: Comma2k19Segment, ref: ReferenceTrajectory) -> dict[str, Any]:
    """Numbers measured against the reference at conversion time (for conversion.yaml)."""
    t_ref = seg.pose_t
    speed_ref = np.linalg.norm(seg.pose_vel_ecef_m_s, axis=1)
    inside = (t_ref >= seg.wheel_t[0]) & (t_ref <= seg.wheel_t[-1]) & (speed_ref > 1.0)
    scale: dict[str, float] = {}
    if np.any(inside):
        for k, name in enumerate(WHEELS):
            ws = np.interp(t_ref[inside], seg.wheel_t, seg.wheel_speed_m_s[:, k])
            sr = speed_ref[inside]
            scale[name] = float(np.dot(ws, sr) / np.dot(sr, sr))
    lat, lon, alt = seg.gnss[:, 0], seg.gnss[:, 1], seg.gnss[:, 4]
    ltp = LocalTangentPlane(*ref.origin_lla)
    gnss_enu = np.column_stack(ltp.to_enu(lat, lon, alt))
    sel = (seg.gnss_t >= t_ref[0]) & (seg.gnss_t <= t_ref[-1]) & np.all(np.isfinite(gnss_enu), 1)
    horizontal_rms = None
    mean_error = None
    if np.any(sel):
        dev = np.column_stack(
            [np.interp(seg.gnss_t[sel], t_ref, ref.device_enu_m[:, k]) for k in range(3)]
        )
        err = gnss_enu[sel] - dev
        horizontal_rms = float(np.sqrt(np.mean(np.sum(err[:, :2] ** 2, axis=1))))
        mean_error = [float(v) for v in err.mean(axis=0)]
    return {
        "wheel_speed_over_reference_speed": scale,
        "gnss_vs_reference_device_position": {
            "horizontal_rms_m": horizontal_rms,
            "mean_enu_error_m": mean_error,
        },
        "reference_start_enu_m": [float(v) for v in ref.position_enu_m[0]],
    }


def _attribution(command: str | None) -> str:
    cmd = command or "tire-estimation convert comma2k19 SEGMENT_DIR --out BAG"
    return attribution(
        """\
This bag is converted from one segment of **comma2k19** by comma.ai
(<https://github.com/commaai/comma2k19>), released under the MIT license (copy in
`LICENSE` next to this file). Paper: H. Schafer, E. Santana, A. Haden, R. Biasini,
"A Commute in Data: The comma2k19 Dataset", arXiv:1812.05752, 2018.

Segment: route `b0c9d2329ad1606b|2018-08-02--08-34-47`, segment 40 (2018 Toyota RAV4,
California route 280), one minute.

The measurements were converted to the tire_estimation contract (units, frames, nominal tyre
radius, steering ratio, device mounting and lever arm); see `conversion.yaml`,
`vehicle.yaml` and `docs/data_comma2k19.md` of the project.""",
        cmd,
    )


def convert_comma2k19(
    segment_dir: Path | str,
    out_dir: Path | str,
    *,
    overwrite: bool = False,
    options: Comma2k19Options | None = None,
    command: str | None = None,
) -> Path:
    """Convert a comma2k19 segment folder to a contract bag directory ``out_dir``.

    The bag holds the input topics, ``/reference/odometry``, ``vehicle.yaml``,
    ``conversion.yaml`` (choices, mounting, reference origin, checks), ``ATTRIBUTION.md``
    (with ``command``) and the dataset ``LICENSE`` when found next to the segment.

    Raises:
        ConvertError: a folder or array is missing or malformed.
        BagError: ``out_dir`` exists (without ``overwrite``) or cannot be written.
    """
    opts = options or Comma2k19Options()
    seg = load_segment(segment_dir)
    series, info = comma2k19_series(seg, opts)
    vehicle = rav4_vehicle(opts)
    origin = info["reference_origin"]
    origin_yaml = yaml.safe_dump([origin["lat_deg"], origin["lon_deg"], origin["alt_m"]])
    license_file = next(
        (c for c in (seg.path / "LICENSE", seg.path.parent / "LICENSE") if c.is_file()), None
    )
    return write_converted_bag(
        out_dir,
        vehicle,
        series,
        info,
        source=f"comma2k19 {seg.path.name}",
        conversion_keys=("clock", "options", "device_mount"),
        attribution_md=_attribution(command),
        vehicle_comment=RAV4_VEHICLE_COMMENT,
        source_files={"LICENSE": license_file},
        custom_data={CUSTOM_ORIGIN: origin_yaml, CUSTOM_REFERENCE_ORIGIN: origin_yaml},
        overwrite=overwrite,
    )


__all__ = [
    "RAV4_NOMINAL_RADIUS_M",
    "Comma2k19Options",
    "Comma2k19Segment",
    "comma2k19_series",
    "convert_comma2k19",
    "load_segment",
    "mount_rotation",
    "rav4_vehicle",
    "reference_trajectory",
    "tire_radius_m",
]
