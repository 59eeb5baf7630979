"""The IMU's mounting yaw from its specific force against the wheels' acceleration."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tire_estimation.core.imu_mounting import (
    EARLY_BLOCKS,
    MIN_BLOCKS,
    ImuMountingCheck,
)

RADIUS_M, TRACK_M = 0.31, 1.55


def _drive(
    check: ImuMountingCheck,
    yaw_deg: float,
    seconds: float = 80.0,
    manoeuvres: bool = True,
    mirror: bool = False,
    seed: int = 0,
    upside_down: bool = False,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Feed ``seconds`` of a drive (speed and yaw rate varying, 100 Hz) whose IMU is turned by
    ``yaw_deg`` (its y axis mirrored with ``mirror``); return base_link's acceleration and what
    the check returned for the last IMU samples."""
    rng = np.random.default_rng(seed)
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    bias = np.array([0.08, -0.05, 0.0])
    out = []
    for k in range(int(seconds * 100)):
        t = 0.01 * k
        t_ns = 1_000_000_000 + 10_000_000 * k
        amp = 1.0 if manoeuvres else 0.0
        v = 15.0 + amp * 5.0 * math.sin(2.0 * math.pi * t / 20.0)
        dv = amp * 5.0 * 2.0 * math.pi / 20.0 * math.cos(2.0 * math.pi * t / 20.0)
        r = amp * 0.1 * math.sin(2.0 * math.pi * t / 15.0)
        half = 0.5 * TRACK_M * r
        ws = np.array([v - half, v + half, v - half, v + half]) / RADIUS_M
        check.on_wheel_speeds(t_ns, ws)
        a = np.array([dv, v * r, 9.81])
        f_imu = np.array([c * a[0] + s * a[1], -s * a[0] + c * a[1], a[2]])
        gyro = np.array([0.0, 0.0, r])
        if mirror:
            f_imu[1] = -f_imu[1]
        if upside_down:
            f_imu[1:], gyro[1:] = -f_imu[1:], -gyro[1:]
        f_imu = f_imu + bias + rng.normal(0.0, 0.05, 3)
        _, f_out = check.on_imu(t_ns + 5_000_000, gyro, f_imu)
        out.append((a, f_out))
    return out


@pytest.mark.parametrize("yaw_deg", [90.0, -90.0, 180.0])
def test_a_right_angle_is_decided_early_and_exactly_and_taken_out(yaw_deg: float) -> None:
    check = ImuMountingCheck(RADIUS_M, TRACK_M)
    rows = _drive(check, yaw_deg)
    res = check.result
    assert res.decided and res.corrected and check.rotating
    assert res.blocks < MIN_BLOCKS  # before a plain decision could be made
    assert res.yaw_deg is not None
    assert (res.yaw_deg - yaw_deg + 180.0) % 360.0 - 180.0 == pytest.approx(0.0)
    assert res.decided_t_ns is not None and res.decided_t_ns < 1_000_000_000 + 20e9
    # the samples after the decision are in base_link axes (up to the bias and the noise)
    a, f = np.array([r[0] for r in rows[-2000:]]), np.array([r[1] for r in rows[-2000:]])
    assert np.sqrt(np.mean((f[:, :2] - a[:, :2]) ** 2)) < 0.15
    assert f[:, 2] == pytest.approx(a[:, 2], abs=0.3)


def test_another_angle_is_decided_from_the_whole_minute_and_taken_out() -> None:
    check = ImuMountingCheck(RADIUS_M, TRACK_M)
    _drive(check, 30.0)
    res = check.result
    assert res.decided and res.corrected and res.blocks >= MIN_BLOCKS
    assert res.yaw_deg == pytest.approx(30.0, abs=1.0)
    assert res.correlation is not None and res.correlation > 0.95


def test_an_imu_mounted_right_is_decided_and_left_as_it_is() -> None:
    check = ImuMountingCheck(RADIUS_M, TRACK_M)
    rows = _drive(check, 3.0)
    res = check.result
    assert res.decided and not res.corrected and not check.rotating
    assert res.yaw_deg == pytest.approx(3.0, abs=1.0)
    # samples pass through unchanged
    f = rows[-1][1]
    assert check.on_imu(0, np.zeros(3), f)[1] is f


def test_no_decision_without_manoeuvres_or_with_a_mirrored_axis() -> None:
    steady = ImuMountingCheck(RADIUS_M, TRACK_M)
    _drive(steady, 90.0, manoeuvres=False)
    assert not steady.result.decided and not steady.rotating
    mirrored = ImuMountingCheck(RADIUS_M, TRACK_M)
    _drive(mirrored, 0.0, mirror=True)
    res = mirrored.result
    assert not res.decided and not mirrored.rotating
    assert res.blocks > EARLY_BLOCKS and res.correlation is not None and res.correlation < 0.7


def test_below_the_speed_floor_nothing_is_fitted() -> None:
    check = ImuMountingCheck(RADIUS_M, TRACK_M)
    for k in range(6000):
        t_ns = 1_000_000_000 + 10_000_000 * k
        check.on_wheel_speeds(t_ns, np.full(4, 1.0 / RADIUS_M))  # 1 m/s
        check.on_imu(t_ns, np.zeros(3), np.array([0.5, 0.0, 9.81]))
    assert check.result.blocks == 0 and check.result.yaw_deg is None


def test_an_imu_upside_down_is_turned_back_before_its_yaw_is_fitted() -> None:
    check = ImuMountingCheck(RADIUS_M, TRACK_M)
    rows = _drive(check, 0.0, upside_down=True)
    res = check.result
    assert res.upside_down and check.rotating
    # once turned back it fits as mounted right: no yaw to correct
    assert res.decided and not res.corrected and abs(res.yaw_deg or 99.0) < 1.0
    a, f = np.array([r[0] for r in rows[-2000:]]), np.array([r[1] for r in rows[-2000:]])
    assert np.sqrt(np.mean((f - a) ** 2)) < 0.15  # z up again, y to the left
    upright = ImuMountingCheck(RADIUS_M, TRACK_M)
    _drive(upright, 0.0)
    assert not upright.result.upside_down and not upright.rotating


def test_upside_down_and_turned_counts_two_changes_of_the_axes() -> None:
    check = ImuMountingCheck(RADIUS_M, TRACK_M)
    rows = _drive(check, 90.0, upside_down=True)
    res = check.result
    # the drive's IMU reads F R(-90 deg) a (F: 180 deg about x); turned back by F first, the
    # yaw left is the drive's
    assert res.upside_down and res.corrected and check.turns == 2
    assert res.yaw_deg == pytest.approx(90.0)
    a, f = np.array([r[0] for r in rows[-2000:]]), np.array([r[1] for r in rows[-2000:]])
    assert np.sqrt(np.mean((f - a) ** 2)) < 0.15
