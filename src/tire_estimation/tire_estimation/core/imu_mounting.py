"""The IMU's mounting: the yaw between its horizontal axes and ``base_link``'s, and whether it is
upside down.

The contract asks for IMU samples in ``base_link`` axes; a driver that publishes in the
sensor's own axes, or a board turned on its mount, rotates the horizontal specific force and
angular rate by the mounting yaw. The stiffness MPF and the lateral filters then read a
braking car as a turning one (on a simulated drive with the IMU turned 90 degrees the
stiffness MPF's yaw rate is 57 deg/s off), and the radius gates and grade read the wrong axis.

The wheels measure the horizontal acceleration of ``base_link`` without the IMU:
``a = (dv/dt, v r)`` with ``v`` the rear wheels' mean speed and ``r`` their speed difference
over the track. An IMU turned by ``psi`` reports ``f = R(-psi) a`` (plus noise, its bias and
the grade's share of gravity), so the angle that carries ``f`` onto ``a`` is the orthogonal
Procrustes solution over the centred block means (Umeyama, IEEE TPAMI 13(4), 1991, for any
dimension), in two dimensions::

    psi = atan2(sum(f_x a_y - f_y a_x), sum(f_x a_x + f_y a_y))

with the correlation ``rho = |(dot, cross)| / sqrt(sum |f|^2 sum |a|^2)`` telling how well one
rotation explains the two. Once the drive has lasted (:data:`MIN_BLOCKS`), accelerated, braked
or turned enough (:data:`MIN_EXCITATION_M2_S4`) and ``rho`` is at least :data:`MIN_CORRELATION`,
the angle is decided; a fit near a right angle (90, 180 or 270 degrees, the usual mounting
error) is decided as that angle after :data:`EARLY_BLOCKS`, so that little is learned from
rotated axes. One of :data:`MIN_CORRECTED_DEG` or more is taken out of every later sample
(accelerometer and gyro x, y); the pipeline restarts the IMU-driven lateral estimators at each
change of the axes (:attr:`ImuMountingCheck.turns`: they learned from other axes). A smaller
angle is reported, not corrected.

A mirrored pair of axes is not a rotation, but with little lateral excitation it fits as well
as one; an angle is decided only while the rotation fits better than the mirror image
(:data:`MIN_MIRROR_MARGIN`). An IMU upside down, or one publishing the aerospace axes (x
forward, y right, z down), reads about -g on z over its first :data:`GRAVITY_SAMPLES` samples:
its samples are turned by 180 degrees about x (into x forward, y left, z up) before the yaw is
fitted.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.radius.model import RL, RR

#: length of the blocks whose means are compared, s (averages out the IMU's vibration and the
#: wheel speeds' quantization in the derivative)
BLOCK_S = 0.5
#: blocks count only while the rear wheels roll at least this fast, m/s
MIN_SPEED_M_S = 3.0
#: blocks needed for a decision (60 s of driving: on simulated drives the first 20 s, a
#: drive-off, fit up to 4 degrees off the whole drive's angle)
MIN_BLOCKS = 120
#: blocks after which a turn by a right angle is decided (an IMU turned on its mount or
#: publishing in its own axes is turned by a multiple of 90 degrees)
EARLY_BLOCKS = 20
#: the correlation of that early decision, 1
EARLY_CORRELATION = 0.85
#: the excitation of that early decision, (m/s^2)^2 (about 200 times the wheels' noise in it)
EARLY_EXCITATION_M2_S4 = 2.0
#: a fitted angle this close to 90, 180 or 270 degrees is that right angle early, deg
RIGHT_ANGLE_TOLERANCE_DEG = 10.0
#: the centred sum of |a|^2 over the blocks needed for a decision, (m/s^2)^2 (e.g. 40 blocks
#: (20 s) of 0.5 m/s^2 RMS manoeuvring)
MIN_EXCITATION_M2_S4 = 10.0
#: the correlation of the fit needed for a decision, 1
MIN_CORRELATION = 0.7
#: a decided angle at least this large is corrected, deg (smaller: reported only)
MIN_CORRECTED_DEG = 15.0
#: a wheel-speed gap longer than this ends the block without using it, s
MAX_GAP_S = 0.2
#: how much better the rotation must fit than the mirror image for a decision, 1
MIN_MIRROR_MARGIN = 0.1
#: IMU samples whose mean vertical specific force tells an IMU upside down
GRAVITY_SAMPLES = 200
#: a mean vertical specific force below this is an IMU upside down, m/s^2 (-g / 2)
UPSIDE_DOWN_BELOW_M_S2 = -4.9


@dataclass(frozen=True)
class MountingResult:
    """What the check found.

    Attributes:
        yaw_deg: the fitted mounting yaw (the angle that turns the IMU's axes onto
            ``base_link``'s), deg; None before enough excitation.
        correlation: how well one rotation carries the IMU's horizontal specific force onto the
            wheels' acceleration, 1 (None: nothing fitted yet).
        decided: the angle is final (enough excitation and correlation).
        corrected: the IMU samples are rotated by ``yaw_deg`` since ``decided_t_ns``.
        decided_t_ns: stamp of the decision, ns (None: not decided).
        blocks: blocks used.
        mirror_correlation: the same for the mirror image (None: nothing fitted yet).
        upside_down: the IMU's z axis points down; its samples are turned by 180 degrees about
            x (before the yaw) from the first :data:`GRAVITY_SAMPLES` on.
    """

    yaw_deg: float | None
    correlation: float | None
    decided: bool
    corrected: bool
    decided_t_ns: int | None
    blocks: int
    mirror_correlation: float | None = None
    upside_down: bool = False


class ImuMountingCheck:
    """Fits the IMU's mounting yaw from block means of its specific force and the rear wheels'
    acceleration (module docstring); rotates the IMU samples once a large angle is decided.

    Args:
        nominal_radius_m: the wheels' nominal rolling radius, m.
        track_width_m: the rear track, m.
    """

    def __init__(self, nominal_radius_m: float, track_width_m: float) -> None:
        self._radius_m = float(nominal_radius_m)
        self._track_m = float(track_width_m)
        self._block_ns = round(BLOCK_S * 1e9)
        # the open block: its start, the speed there, sums of v r and of f over it
        self._t0_ns: int | None = None
        self._v0 = 0.0
        self._t_wheel_ns: int | None = None
        self._v = 0.0
        self._vr_sum = 0.0
        self._n_wheel = 0
        self._f_sum = np.zeros(2)
        self._n_imu = 0
        # sums over the used blocks: of f, a, f.f, a.a, fx ax, fy ay, fx ay, fy ax
        self._sums = np.zeros(10)
        self._blocks = 0
        # the decided yaw's rotation
        self._cos, self._sin = 1.0, 0.0
        # the vertical specific force of the first samples (the gravity check)
        self._fz_sum, self._fz_n = 0.0, 0
        self._gravity_checked = False
        self.result = MountingResult(None, None, False, False, None, 0)

    @property
    def rotating(self) -> bool:
        """The IMU samples are being turned into ``base_link`` (a yaw, or upside down)."""
        return self.result.corrected or self.result.upside_down

    @property
    def turns(self) -> int:
        """How many times the turn applied to the samples changed (0, 1 or 2): a consumer that
        learned from the samples before a change learned from other axes."""
        return int(self.result.upside_down) + int(self.result.corrected)

    def on_wheel_speeds(self, t_ns: int, wheel_speed_rad_s: F64) -> None:
        """Advance the block with the rear wheels' speed and yaw rate."""
        if self.result.decided:
            return
        w_l, w_r = float(wheel_speed_rad_s[RL]), float(wheel_speed_rad_s[RR])
        if not (math.isfinite(w_l) and math.isfinite(w_r)):
            self._t0_ns = None
            return
        v = 0.5 * self._radius_m * (w_l + w_r)
        yaw_rate = self._radius_m * (w_r - w_l) / self._track_m
        gap = self._t_wheel_ns is not None and t_ns - self._t_wheel_ns > MAX_GAP_S * 1e9
        self._t_wheel_ns = t_ns
        if gap or v < MIN_SPEED_M_S:
            self._t0_ns = None
            return
        if self._t0_ns is None:
            self._open(t_ns, v)
            return
        self._v = v
        self._vr_sum += v * yaw_rate
        self._n_wheel += 1
        if t_ns - self._t0_ns >= self._block_ns:
            self._close(t_ns)
            self._open(t_ns, v)

    def on_imu(self, t_ns: int, gyro_rad_s: F64, accel_m_s2: F64) -> tuple[F64, F64]:
        """Take the sample into the open block; return it in ``base_link`` axes (turned once an
        IMU upside down or a large mounting yaw is decided, else as given)."""
        if not self._gravity_checked:
            self._check_gravity(float(accel_m_s2[2]))
            return gyro_rad_s, accel_m_s2
        if self.result.upside_down:
            # 180 degrees about x: y and z change sign
            gyro_rad_s = np.array([gyro_rad_s[0], -gyro_rad_s[1], -gyro_rad_s[2]])
            accel_m_s2 = np.array([accel_m_s2[0], -accel_m_s2[1], -accel_m_s2[2]])
        if self.result.corrected:
            return self._rotated(gyro_rad_s), self._rotated(accel_m_s2)
        if not self.result.decided and self._t0_ns is not None:
            fx, fy = float(accel_m_s2[0]), float(accel_m_s2[1])
            if math.isfinite(fx) and math.isfinite(fy):
                self._f_sum[0] += fx
                self._f_sum[1] += fy
                self._n_imu += 1
        return gyro_rad_s, accel_m_s2

    def _check_gravity(self, fz: float) -> None:
        if not math.isfinite(fz):
            return
        self._fz_sum += fz
        self._fz_n += 1
        if self._fz_n >= GRAVITY_SAMPLES:
            self._gravity_checked = True
            upside_down = self._fz_sum / self._fz_n < UPSIDE_DOWN_BELOW_M_S2
            self.result = dataclasses.replace(self.result, upside_down=upside_down)

    def _rotated(self, xyz: F64) -> F64:
        c, s = self._cos, self._sin
        x, y = float(xyz[0]), float(xyz[1])
        return np.array([c * x - s * y, s * x + c * y, float(xyz[2])])

    def _open(self, t_ns: int, v: float) -> None:
        self._t0_ns, self._v0, self._v = t_ns, v, v
        self._vr_sum, self._n_wheel = 0.0, 0
        self._f_sum[:] = 0.0
        self._n_imu = 0

    def _close(self, t_ns: int) -> None:
        assert self._t0_ns is not None
        if self._n_imu == 0 or self._n_wheel == 0:
            return
        dt_s = (t_ns - self._t0_ns) * 1e-9
        ax, ay = (self._v - self._v0) / dt_s, self._vr_sum / self._n_wheel
        fx, fy = self._f_sum / self._n_imu
        self._sums += (fx, fy, ax, ay, fx * fx + fy * fy, ax * ax + ay * ay,
                       fx * ax, fy * ay, fx * ay, fy * ax)  # fmt: skip
        self._blocks += 1
        self._fit(t_ns)

    def _fit(self, t_ns: int) -> None:
        n = self._blocks
        sfx, sfy, sax, say, sff, saa, sxx, syy, sxy, syx = self._sums
        # centred sums: the IMU's bias and the grade's share of gravity drop out
        cff = sff - (sfx * sfx + sfy * sfy) / n
        caa = saa - (sax * sax + say * say) / n
        cxx, cyy = sxx - sfx * sax / n, syy - sfy * say / n
        cxy, cyx = sxy - sfx * say / n, syx - sfy * sax / n
        if cff <= 0.0 or caa <= 0.0:
            return
        # 2-D orthogonal Procrustes: the rotation carrying f onto a (module docstring)
        cdot, ccross = cxx + cyy, cxy - cyx
        yaw = math.atan2(ccross, cdot)
        rho = math.hypot(cdot, ccross) / math.sqrt(cff * caa)
        # the same for the mirror image (f_y negated): a decision needs the rotation to fit better
        rho_mirror = math.hypot(cxx - cyy, cxy + cyx) / math.sqrt(cff * caa)
        distinct = rho - rho_mirror >= MIN_MIRROR_MARGIN
        yaw_deg = math.degrees(yaw)
        quarter = round(yaw_deg / 90.0)
        right_angle = (
            quarter % 4 != 0
            and abs(yaw_deg - 90.0 * quarter) <= RIGHT_ANGLE_TOLERANCE_DEG
            and rho >= EARLY_CORRELATION
            and distinct
        )
        early = n >= EARLY_BLOCKS and caa >= EARLY_EXCITATION_M2_S4 and n < MIN_BLOCKS
        if early and right_angle:
            # a right angle: taken exactly (the early fit is a few degrees off)
            yaw_deg = 90.0 * quarter
            yaw = math.radians(yaw_deg)
            decided = True
        else:
            decided = (
                n >= MIN_BLOCKS
                and caa >= MIN_EXCITATION_M2_S4
                and rho >= MIN_CORRELATION
                and distinct
            )
        corrected = decided and abs(yaw_deg) >= MIN_CORRECTED_DEG
        if corrected:
            self._cos, self._sin = math.cos(yaw), math.sin(yaw)
        self.result = MountingResult(
            yaw_deg=yaw_deg,
            correlation=rho,
            decided=decided,
            corrected=corrected,
            decided_t_ns=t_ns if decided else None,
            blocks=n,
            mirror_correlation=rho_mirror,
            upside_down=self.result.upside_down,
        )
