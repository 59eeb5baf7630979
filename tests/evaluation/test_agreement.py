"""Sensor agreement: the relations sized on a synthetic drive whose truth is known exactly.

The drive: speed 20 m/s +- 6 m/s (90-s period) and a lateral specific force of +-3 m/s^2
(23-s period) on the path this yaw rate draws, 10 Hz velocities with 0.05 m/s and fixes with
0.3 m white noise per axis, a gyro with 0.002 rad/s white noise, a nominal 0.31 m tyre whose
radius error drifts by 0.2 mm over the drive. Each effect is put
into the wheel speeds or the velocity as its definition says; the fit must size it and the
others must stay below the threshold.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from tire_estimation.evaluation import agreement
from tire_estimation.evaluation.residuals import SCORE_THRESHOLD, _with_agreement

RN = 0.31
LT = 1.55
PARAMS = {
    "nominal_radius_m": RN,
    "track_width_m": LT,
    "mass_kg": 1500.0,
    "cg_height_m": 0.55,
    "cg_to_front_axle_m": 1.1,
    "wheelbase_m": 2.7,
    "velocity_shift_s": 0.0,
    "lever_arm_y_m": 0.0,
    "fix_shift_s": 0.0,
}


def _drive(
    seed: int = 0,
    minutes: float = 8.0,
    wheel_offset_s: float = 0.0,
    speed_coeff: float = 0.0,
    load_coeff: float = 0.0,
    learning: bool = True,
    fix_latency_s: float = 0.0,
    velocity_latency_s: float = 0.0,
    nan_every: int = 0,
    antenna_x_m: float = 0.0,
    declared_antenna_x_m: float = 0.0,
    antenna_y_m: float = 0.0,
    lateral_m_s2: float = 3.0,
) -> np.ndarray:
    rng = np.random.default_rng(seed)
    bins = agreement.AgreementBins(RN, LT, lever_arm_x_m=declared_antenna_x_m)
    dt = 0.1
    t = np.arange(0.0, 60.0 * minutes, dt)

    def speed(tt: Any) -> Any:
        return 20.0 + 6.0 * np.sin(2 * math.pi * tt / 90.0)

    fy = lateral_m_s2 * np.sin(2 * math.pi * t / 23.0)
    yaw = fy / speed(t)
    # the path: heading and position by the trapezoidal rule on a 10-ms grid
    tf = np.arange(-1.0, t[-1] + 0.01, 0.01)
    yaw_f = lateral_m_s2 * np.sin(2 * math.pi * tf / 23.0) / speed(tf)
    psi = np.concatenate([[0.0], np.cumsum(0.5 * (yaw_f[1:] + yaw_f[:-1]) * 0.01)])
    vel_f = speed(tf)[:, None] * np.column_stack([np.cos(psi), np.sin(psi)])
    pos_f = np.vstack([np.zeros(2), np.cumsum(0.5 * (vel_f[1:] + vel_f[:-1]) * 0.01, axis=0)])

    def at(x: np.ndarray, tt: np.ndarray) -> np.ndarray:
        return np.column_stack([np.interp(tt, tf, x[:, i]) for i in range(2)])

    drift = 2e-4 * t / t[-1]
    # the wheels stamped t read the speed of t - offset; r = r_n + drift + k v^2
    v_w = speed(t - wheel_offset_s)
    radius = RN + drift + speed_coeff * v_w**2
    omega = v_w / radius
    # rear load transfer dFz = m fy h lf / (lT L), r_i = r + -c dFz
    dfz = PARAMS["mass_kg"] * fy * 0.55 * 1.1 / (LT * 2.7)
    w_l = (omega - yaw * LT / 2.0 / radius) * radius / (radius - load_coeff * dfz)
    w_r = (omega + yaw * LT / 2.0 / radius) * radius / (radius + load_coeff * dfz)
    vel = at(vel_f, t - velocity_latency_s) + rng.normal(0.0, 0.05, (t.size, 2))
    # an antenna ahead of the rear axle moves sideways at yaw rate x its offset
    heading = np.interp(t - velocity_latency_s, tf, psi)
    vel += (yaw * antenna_x_m)[:, None] * np.column_stack([-np.sin(heading), np.cos(heading)])
    # ... and one to the left of it along the track at minus yaw rate x its offset
    vel -= (yaw * antenna_y_m)[:, None] * np.column_stack([np.cos(heading), np.sin(heading)])
    fix = at(pos_f, t - fix_latency_s) + rng.normal(0.0, 0.3, (t.size, 2))
    fix_heading = np.interp(t - fix_latency_s, tf, psi)
    fix += antenna_x_m * np.column_stack([np.cos(fix_heading), np.sin(fix_heading)])
    fix += antenna_y_m * np.column_stack([-np.sin(fix_heading), np.cos(fix_heading)])
    if nan_every:
        vel[::nan_every] = np.nan
    for k in range(t.size):
        stamp = round(t[k] * 1e9) + 1_000_000_000
        # a fix before the velocity of its stamp (the pipeline's order)
        bins.add_fix(stamp, (float(fix[k, 0]), float(fix[k, 1])), learning)
        bins.add(
            stamp, np.array([vel[k, 0], vel[k, 1], 0.0]),
            (float(w_l[k]), float(w_r[k])), float(yaw[k] + rng.normal(0.0, 0.002)),
            float(fy[k]), 0.0, learning, False,
        )  # fmt: skip
    bins.flush()
    return np.array(bins.rows)


def _fit(rows: np.ndarray, **params: float) -> dict[str, Any]:
    return agreement.analyze(rows, {**PARAMS, **params}, SCORE_THRESHOLD)


def _significant(res: dict[str, Any]) -> set[str]:
    return {
        name
        for relation in res.values()
        for name, fit in relation.items()
        if isinstance(fit, dict) and fit["significant"]
    }


def test_a_clean_drive_has_no_significant_effect() -> None:
    res = _fit(_drive())
    assert res["speed"]["bins"] >= 400
    assert _significant(res) == set()
    assert abs(res["speed"]["time_alignment"]["estimate"]) < 0.01


def test_the_sideways_speed_of_an_antenna_ahead_of_the_axle_is_taken_out() -> None:
    # 6 m ahead (a truck's cab): the Doppler ground speed exceeds the rear axle's by
    # (r a_x)^2 / (2 v), about 10 mm/s on this drive
    # (against the same drive with the antenna over the axle: the tyre's radius error is in
    # both)
    col = agreement.COLUMNS.index("v_gnss_m_s"), agreement.COLUMNS.index("u_m_s")
    over_axle = _drive()
    undeclared = _drive(antenna_x_m=6.0)
    declared = _drive(antenna_x_m=6.0, declared_antenna_x_m=6.0)
    excess = [
        float(
            np.mean(
                rows[:, col[0]] - rows[:, col[1]] - over_axle[:, col[0]] + over_axle[:, col[1]]
            )
        )
        for rows in (undeclared, declared)
    ]
    assert excess[0] > 0.006
    assert abs(excess[1]) < 0.001
    assert _significant(_fit(declared)) == set()


def test_a_wheel_speed_time_offset_is_sized() -> None:
    res = _fit(_drive(wheel_offset_s=0.1))
    fit = res["speed"]["time_alignment"]
    assert fit["estimate"] == pytest.approx(0.1, abs=0.01)
    assert _significant(res) == {"time_alignment"}


def test_a_declared_offset_is_not_reported_again() -> None:
    # a declared wheel-speed time offset shifts the fixes and the velocities alike
    res = _fit(_drive(wheel_offset_s=0.1), velocity_shift_s=0.1, fix_shift_s=0.1)
    assert abs(res["speed"]["time_alignment"]["estimate"]) < 0.01
    assert _significant(res) == set()


def test_a_speed_dependent_radius_is_sized() -> None:
    res = _fit(_drive(speed_coeff=4e-6))
    assert res["speed"]["radius_speed_dependence"]["estimate"] == pytest.approx(4e-6, rel=0.1)
    assert _significant(res) == {"radius_speed_dependence"}


def test_a_load_dependent_radius_is_sized_from_the_gyro() -> None:
    res = _fit(_drive(load_coeff=-2e-6))
    assert res["yaw_rate"]["radius_load_dependence"]["estimate"] == pytest.approx(-2e-6, rel=0.1)
    assert _significant(res) == {"radius_load_dependence"}


def test_a_fix_latency_is_sized_against_the_integrated_velocity() -> None:
    res = _fit(_drive(fix_latency_s=0.2))
    assert res["position"]["gnss_latency"]["estimate"] == pytest.approx(0.2, abs=0.02)
    assert _significant(res) == {"gnss_latency"}


def test_a_velocity_latency_is_not_read_as_a_fix_latency() -> None:
    res = _fit(_drive(velocity_latency_s=0.2))
    assert res["speed"]["time_alignment"]["estimate"] == pytest.approx(-0.2, abs=0.02)
    assert res["position"]["fix_vs_velocity_s"] == pytest.approx(0.2, abs=0.02)
    assert abs(res["position"]["gnss_latency"]["estimate"]) < 0.02
    assert _significant(res) == {"time_alignment"}


def test_a_declared_fix_latency_is_not_reported_again() -> None:
    res = _fit(_drive(fix_latency_s=0.2), fix_shift_s=-0.2)
    assert abs(res["position"]["gnss_latency"]["estimate"]) < 0.02
    assert _significant(res) == set()


def test_a_velocity_that_is_not_finite_is_left_out() -> None:
    # one velocity in 50 is NaN: the fits stay finite and still size a fix latency
    rows = _drive(fix_latency_s=0.2, nan_every=50)
    assert np.all(np.isfinite(rows[:, agreement.COLUMNS.index("u_m_s")]))
    res = _fit(rows)
    assert res["position"]["gnss_latency"]["estimate"] == pytest.approx(0.2, abs=0.02)
    assert _significant(res) == {"gnss_latency"}


def test_a_small_effect_is_significant_but_not_material() -> None:
    # 0.01 s: a t far above the threshold, a speed change of about 0.005 % RMS
    fit = _fit(_drive(wheel_offset_s=0.01, minutes=20.0))["speed"]["time_alignment"]
    assert abs(fit["t"]) >= SCORE_THRESHOLD
    assert fit["relative_rms"] < agreement.MATERIAL_FRACTION
    assert not fit["significant"]


def test_a_lateral_antenna_offset_fails_the_verdict_by_its_size_in_gentle_turns(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # 0.3 m right of the axle in 0.5 m/s^2 turns: the wheel speeds change by less than the
    # material 0.05 %, the pose by 0.3 m
    rows = _drive(antenna_y_m=-0.3, lateral_m_s2=0.5)
    fit = _fit(rows)["speed"]["gnss_lever_arm_y"]
    assert fit["estimate"] == pytest.approx(-0.3, abs=0.05)
    assert abs(fit["t"]) >= SCORE_THRESHOLD
    assert fit["relative_rms"] < agreement.MATERIAL_FRACTION
    assert fit["significant"]
    monkeypatch.setattr(agreement, "MATERIAL_LEVER_ARM_M", 0.4)
    assert not _fit(rows)["speed"]["gnss_lever_arm_y"]["significant"]


def test_nothing_is_tested_while_nothing_is_learned() -> None:
    res = _fit(_drive(learning=False))
    assert all("note" in res[relation] for relation in ("speed", "yaw_rate", "position"))


def test_a_negative_alignment_is_a_velocity_latency() -> None:
    fit = {"estimate": -0.2, "t": -30.0, "relative_rms": 1e-3, "significant": True}
    effects = _with_agreement([], {"speed": {"time_alignment": fit}})
    by_name = {e["effect"]: e for e in effects}
    assert by_name["gnss_velocity_latency"]["estimate"] == pytest.approx(0.2)
    assert by_name["gnss_velocity_latency"]["score"] == pytest.approx(30.0)
    assert by_name["wheel_speed_time_offset"]["score"] == 0.0
