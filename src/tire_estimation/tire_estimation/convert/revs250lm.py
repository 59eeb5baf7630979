"""Revs program Ferrari 250 LM run (text export of the sideslip benchmark) -> contract bag.

Input: a folder of one-column text files of equal length (100 Hz), ``t`` (s), ``vx``, ``vy``
(m/s at the centre of gravity, INS), ``yawRate`` (rad/s), ``axCG``, ``ayCG`` (m/s^2 at the
CG), ``delta`` (mean road-wheel steer angle, rad), ``beta_true`` (rad, atan(vy/vx), used as a
consistency check). There are no wheel speeds and no GNSS.

Signs: ``ayCG`` = d(vy)/dt + vx * yawRate (mean residual 0.03 m/s^2) and ``delta`` correlates
+0.97 with ``yawRate``, so the export uses one consistent axis convention, taken as ISO 8855
(x forward, y left, z up), as the benchmark's models do. The mean ``ayCG`` of -1.5 m/s^2 is
matched by the mean ``vx * yawRate`` (-1.54): the circuit is driven clockwise (the heading
changes by -1985 deg in 550 s), it is not an accelerometer offset.

Output topics (stamps = ``t`` in ns):

* ``/vehicle/steering``: ``delta``.
* ``/imu/data``: angular velocity ``(0, 0, yawRate)`` (roll and pitch rates are not in the
  export), specific force ``(axCG, ayCG, +g)`` (vertical not in the export; level road).
  The IMU position in ``vehicle.yaml`` is the CG.
* ``/vehicle/velocity`` (project-defined input, ``geometry_msgs/TwistWithCovarianceStamped``
  in ``base_link``): the measured longitudinal speed ``vx`` as ``linear.x`` (vx of the CG =
  vx of the rear-axle centre for a rigid body); ``linear.y``/``linear.z`` are 0 with the
  variance :data:`~tire_estimation.convert.common.UNMEASURED_VELOCITY_VARIANCE` (not an
  input). Wheel speeds synthesized from vx would pretend to a measurement that does not
  exist, so none are written.
* ``/reference/odometry``: twist of base_link in base_link axes, ``linear = (vx,
  vy - lr * yawRate, 0)`` (lateral velocity moved from the CG to the rear axle),
  ``angular = (0, 0, yawRate)``. There is no position: the pose is dead-reckoned from these
  velocities (origin 0, heading 0 at the start) and its covariance is marked unmeasured
  (:data:`~tire_estimation.convert.common.UNMEASURED_POSE_VARIANCE`).
* ``/reference/lateral_state`` (project-defined, ``sensor_msgs/JointState``, ``position``):
  ``vx_cg`` (m/s), ``vy_cg`` (m/s), ``sideslip_cg`` (rad, atan2(vy, vx) = ``beta_true``),
  ``yaw_rate`` (rad/s) exactly as measured.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from tire_estimation.bag import topics as tp
from tire_estimation.bag.writer import (
    TopicSeries,
    imu_series,
    joint_series,
    odometry_series,
    velocity_series,
)
from tire_estimation.convert.common import (
    STANDARD_GRAVITY_M_S2,
    UNMEASURED_POSE_VARIANCE,
    UNMEASURED_VELOCITY_VARIANCE,
    ConvertError,
    attribution,
    diff_noise_std,
    require_dir,
    seconds_to_ns,
    write_converted_bag,
    yaw_quaternions_xyzw,
)
from tire_estimation.core.arrays import F64
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.sim.streams import ImuStream

WHAT = "revs250lm data"
#: Project-defined input topic: measured body velocity (TwistWithCovarianceStamped, base_link).
VEHICLE_VELOCITY = tp.VEHICLE_VELOCITY
#: Project-defined reference topic: measured lateral state at the CG (JointState positions).
REFERENCE_LATERAL = tp.REFERENCE_LATERAL_STATE
LATERAL_NAMES = tp.REFERENCE_LATERAL_NAMES
COLUMNS = ("t", "vx", "vy", "yawRate", "axCG", "ayCG", "delta", "beta_true")

REVS_VEHICLE_COMMENT = """\
Ferrari 250 LM (1964) of the Stanford Revs program, run 20140222_01_01_03_250lm, with the
numbers of the sideslip benchmark MBDS/sideslip-angle-vehicle-estimation (README of the data):
mass 982 kg; lf 1.33 m, lr 1.07 m (wheelbase 2.40 m = lf + lr); track 1.35 m;
cg_height_m 1.115 m AS GIVEN (equal to the car's overall height, so probably not the real CG
height, which is likely nearer 0.4 m: it only matters for load transfer);
yaw inertia m / 12 (1.7^2 + 4.09^2) = 1605 kg m^2 (box of width 1.7 m, length 4.09 m);
nominal_tire_radius_m 0.320 m = the rear (driven) rolling radius; the front is 0.298 m
(no wheel speeds in the export, so the radius is not used for inputs);
drive rear (mid-engine, rear-wheel drive);
imu_position_m: the CG (accelerations and velocities are given at the CG);
gnss_antenna_position_m: no GNSS in the export (0, 0, 0);
steering_ratio: not used (delta is the road-wheel angle); cornering / longitudinal
stiffness: project defaults, not measurements of this car.
"""


def revs_vehicle() -> VehicleParams:
    """The Ferrari 250 LM of the Revs data (numbers in :data:`REVS_VEHICLE_COMMENT`)."""
    mass = 982.0
    return VehicleParams(
        name="ferrari_250lm_revs",
        nominal_tire_radius_m=0.320,
        track_width_m=1.35,
        wheelbase_m=2.40,
        cg_to_front_axle_m=1.33,
        cg_to_rear_axle_m=1.07,
        cg_height_m=1.115,
        mass_kg=mass,
        yaw_inertia_kg_m2=round(mass / 12.0 * (1.7**2 + 4.09**2), 1),
        drive="rear",
        gnss_antenna_position_m=(0.0, 0.0, 0.0),
        imu_position_m=(1.07, 0.0, 1.115),
    )


def load_revs(data_dir: Path | str) -> dict[str, F64]:
    """The columns of :data:`COLUMNS` as float arrays; :class:`ConvertError` names problems."""
    root = require_dir(Path(data_dir), WHAT)
    out: dict[str, F64] = {}
    for name in COLUMNS:
        path = root / f"{name}.txt"
        if not path.is_file():
            raise ConvertError(f"{WHAT}: missing file {path}")
        try:
            out[name] = np.loadtxt(path, dtype=np.float64, ndmin=1)
        except ValueError as exc:
            raise ConvertError(f"{WHAT}: cannot parse {path}: {exc}") from exc
        if out[name].ndim != 1:
            raise ConvertError(f"{WHAT}: {path} is not a single column")
    n = len(out["t"])
    for name, arr in out.items():
        if len(arr) != n:
            raise ConvertError(f"{WHAT}: {name}.txt has {len(arr)} rows, t.txt has {n}")
        if not np.all(np.isfinite(arr)):
            raise ConvertError(f"{WHAT}: {name}.txt has non-finite values")
    if n < 2 or not np.all(np.diff(out["t"]) > 0):
        raise ConvertError(f"{WHAT}: t.txt is not strictly increasing")
    return out


def dead_reckon(t_s: F64, vx: F64, vy: F64, yaw_rate: F64) -> tuple[F64, F64]:
    """Planar pose (M, 3) m and heading (M,) rad from body velocities (trapezoidal rule)."""
    dt = np.diff(t_s)
    yaw = np.r_[0.0, np.cumsum(0.5 * (yaw_rate[1:] + yaw_rate[:-1]) * dt)]
    ve = vx * np.cos(yaw) - vy * np.sin(yaw)
    vn = vx * np.sin(yaw) + vy * np.cos(yaw)
    east = np.r_[0.0, np.cumsum(0.5 * (ve[1:] + ve[:-1]) * dt)]
    north = np.r_[0.0, np.cumsum(0.5 * (vn[1:] + vn[:-1]) * dt)]
    return np.column_stack([east, north, np.zeros_like(east)]), yaw


def _corr(a: F64, b: F64) -> float | None:
    """Correlation coefficient, None when either signal is constant."""
    if np.std(a) == 0.0 or np.std(b) == 0.0:
        return None
    return float(np.corrcoef(a, b)[0, 1])


def revs_series(
    data: dict[str, F64], vehicle: VehicleParams | None = None
) -> tuple[list[TopicSeries], dict[str, Any]]:
    """Topic series of the Revs export and a record of the conversion."""
    veh = vehicle or revs_vehicle()
    t_ns = seconds_to_ns(data["t"])
    if not np.all(np.diff(t_ns) > 0):
        raise ConvertError(f"{WHAT}: t.txt has samples closer than 1 ns")
    n = len(t_ns)
    vx, vy, r = data["vx"], data["vy"], data["yawRate"]
    zeros = np.zeros(n)
    series: list[TopicSeries] = [
        joint_series(tp.STEERING, t_ns, ("front_wheel_angle",), "position", data["delta"])
    ]

    gyro_std = float(diff_noise_std(r))
    accel_std = float(np.mean(diff_noise_std(np.column_stack([data["axCG"], data["ayCG"]]))))
    imu = ImuStream(
        t_ns,
        np.column_stack([zeros, zeros, r]),
        np.column_stack([data["axCG"], data["ayCG"], np.full(n, STANDARD_GRAVITY_M_S2)]),
        gyro_noise_std_rad_s=gyro_std,
        accel_noise_std_m_s2=accel_std,
    )
    series.append(imu_series(imu))

    vx_std = float(diff_noise_std(vx))
    vcov = np.zeros((n, 3, 3))
    vcov[:, 0, 0] = vx_std**2
    vcov[:, 1, 1] = vcov[:, 2, 2] = UNMEASURED_VELOCITY_VARIANCE
    vel = velocity_series(
        VEHICLE_VELOCITY, t_ns, np.column_stack([vx, zeros, zeros]), vcov, frame_id=tp.BASE_LINK
    )
    if vel is None:
        raise ConvertError(f"{WHAT}: no finite vx")
    series.append(vel)

    vy_base = vy - veh.cg_to_rear_axle_m * r
    position, yaw = dead_reckon(data["t"], vx, vy_base, r)
    pose_cov = np.zeros((n, 6, 6))
    pose_cov[:, [0, 1, 2, 5], [0, 1, 2, 5]] = UNMEASURED_POSE_VARIANCE
    series.append(
        odometry_series(
            tp.REFERENCE_ODOMETRY,
            t_ns,
            position,
            yaw_quaternions_xyzw(yaw),
            np.column_stack([vx, vy_base, zeros]),
            np.column_stack([zeros, zeros, r]),
            pose_covariance=pose_cov,
        )
    )
    sideslip = np.arctan2(vy, vx)
    lateral = np.column_stack([vx, vy, sideslip, r])
    series.append(joint_series(REFERENCE_LATERAL, t_ns, LATERAL_NAMES, "position", lateral))

    ay_residual = data["ayCG"] - (np.gradient(vy, data["t"]) + vx * r)
    info: dict[str, Any] = {
        "source": "revs250lm",
        "clock": "t.txt (s) * 1e9",
        "span_s": [float(data["t"][0]), float(data["t"][-1])],
        "samples": n,
        "topics": {
            VEHICLE_VELOCITY: "input (project-defined): measured vx in base_link, "
            "TwistWithCovarianceStamped, y/z unmeasured",
            REFERENCE_LATERAL: "reference (project-defined): JointState positions "
            + ", ".join(LATERAL_NAMES),
            tp.REFERENCE_ODOMETRY: "twist of base_link (vy moved from the CG to the rear "
            "axle); pose dead-reckoned, covariance marked unmeasured",
        },
        "noise_std": {"yaw_rate_rad_s": gyro_std, "accel_m_s2": accel_std, "vx_m_s": vx_std},
        "checks": {
            "max_abs_beta_true_minus_atan2_vy_vx_rad": float(
                np.max(np.abs(data["beta_true"] - sideslip))
            ),
            "ay_minus_dvy_dt_plus_vx_r_mean_m_s2": float(np.mean(ay_residual)),
            "ay_minus_dvy_dt_plus_vx_r_std_m_s2": float(np.std(ay_residual)),
            "mean_ay_m_s2": float(np.mean(data["ayCG"])),
            "mean_vx_times_yaw_rate_m_s2": float(np.mean(vx * r)),
            "heading_change_deg": float(math.degrees(yaw[-1])),
            "corr_delta_yaw_rate": _corr(data["delta"], r),
        },
    }
    return series, info


def _attribution(command: str | None) -> str:
    cmd = command or "tire-estimation convert revs250lm DATA_DIR --out BAG"
    return attribution(
        """\
Converted from the Stanford Revs program measurements of a 1964 Ferrari 250 LM (Targa
Sixty-Six 2014, run `20140222_01_01_03_250lm`, samples 15000-70000) as exported by the
open-source benchmark `MBDS/sideslip-angle-vehicle-estimation` (Leanza, Reina,
Blanco-Claraco, "A Factor-Graph-Based Approach to Vehicle Sideslip Angle Estimation",
Sensors 21(16):5409, 2021); that repository's license is in `LICENSE-of-source-repo`.
For evaluation only: do not commit this bag or copies of the data.""",
        cmd,
    )


def convert_revs250lm(
    data_dir: Path | str,
    out_dir: Path | str,
    *,
    overwrite: bool = False,
    command: str | None = None,
) -> Path:
    """Convert the Revs 250 LM text export in ``data_dir`` to a bag directory ``out_dir``.

    Raises:
        ConvertError: a file is missing, unparsable or inconsistent.
        BagError: ``out_dir`` exists (without ``overwrite``) or cannot be written.
    """
    data = load_revs(data_dir)
    vehicle = revs_vehicle()
    series, info = revs_series(data, vehicle)
    license_file = Path(data_dir) / "LICENSE-of-source-repo"
    return write_converted_bag(
        out_dir,
        vehicle,
        series,
        info,
        source="revs250lm 20140222_01_01_03_250lm",
        conversion_keys=("clock", "topics"),
        attribution_md=_attribution(command),
        vehicle_comment=REVS_VEHICLE_COMMENT,
        source_files={license_file.name: license_file},
        overwrite=overwrite,
    )
