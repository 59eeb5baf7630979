"""Residual analysis of the GNSS innovations: consistency tests, regressions, suspected effects.

The innovations ``nu_k = y_k - h(x_k)`` of the radius estimator are rotated into the vehicle's
along-track / cross-track axes with the estimated heading ``psi_k``::

    nu_along = cos(psi) nu_e + sin(psi) nu_n,   nu_cross = -sin(psi) nu_e + cos(psi) nu_n

and tested (NIS against chi-square(2) bounds, Ljung-Box whiteness) and regressed on candidate
regressors (speed, speed^2, longitudinal / lateral acceleration, yaw rate, heading, time).

Library of unmodelled effects and their signature in the innovations (first order, before the
filter absorbs part of a slowly varying residual into its position states):

* ``gnss_latency`` (fix stamped ``t`` describes the antenna at ``t - tau``):
  ``nu_along = -v tau``; the filter absorbs the slowly varying part into its position, what
  stays is about its rate ``-a_x tau`` -> negative slope of along-track on the longitudinal
  acceleration (fitted with intercept and time as nuisance regressors).
* ``wheel_speed_time_offset`` (wheel samples stamped ``t`` describe ``t - d``): the odometry
  pose lags by ``v d`` -> ``nu_along = +v d`` -> positive slope on ``a_x``. Both are delays
  (>= 0), so the sign of the slope separates them.
* ``gnss_lever_arm`` (antenna at ``a = (a_x, a_y)`` in base_link, not declared): the fix is
  ``p + R(psi) a`` -> ``nu_e = a_x cos psi - a_y sin psi + c_e``,
  ``nu_n = a_x sin psi + a_y cos psi + c_n`` (constants ``c`` for the part the position states
  absorbed) -> regressor ``heading``; estimate ``a_x`` (m, reported), ``a_y`` in the tests.
  A forward offset ``a_x`` is nearly unobservable for this filter: the antenna point then moves
  like a unicycle whose heading is offset by ``atan(a_x kappa)`` (``kappa`` the path curvature),
  which the filter absorbs into its heading (1.2 m gave no likelihood change on the 2-minute
  test drive). A lateral offset ``a_y`` moves the antenna at ``v - r a_y`` (``r`` yaw rate), an
  along-track speed error in curves that the filter absorbs into the radii (``gnss_lever_arm_y``
  of the profile ranking, regressor ``yaw_rate``).
* ``radius_speed_dependence`` (``r = r0 + k v^2``): a speed error ``v k v^2 / r0`` integrates
  into an along-track drift -> along-track on speed^2 beyond speed; the regression gives no
  reliable size (the filter absorbs the drift), so ``estimate`` is from the profile scan only.
  :func:`speed_dependence_fit` sizes it directly (batch least squares of the fixes on the
  rear-wheel odometry with ``r0`` constant, no re-runs), with a standard error.
* ``radius_load_dependence`` (``r_i = r0_i + c dFz_i``, lateral load transfer
  ``dFz = -+ m a_y h lf / (l_T L)`` on the rear left / right): the left-right radius difference
  ``2 c dFz`` gives a yaw-rate error ``omega 2 c dFz / l_T`` proportional to ``v a_y``, which
  turns the predicted track to the inside (``c < 0``) -> cross-track innovation on ``v a_y``
  (negative slope for ``c < 0``), fitted with intercept and time; ``a_y = v r`` with the wheel
  speeds' yaw rate ``r`` (the estimated heading's derivative carries each fix's correction,
  which follows the fix's own innovation).
* ``road_grade`` (wheels roll along the slope, GNSS measures the horizontal displacement
  ``ds cos(theta)``): the odometry is long by ``v (1 - cos theta)`` -> along-track innovation on
  ``v (1 - cos theta)`` with the estimator's online grade (negative slope), intercept and time as
  nuisance regressors. Size: the profile of the correction gain (1 = the geometric correction
  with the online grade).
* ``rear_brake_slip`` (the braked rear wheels turn slower, ``omega r = v (1 - k b)`` with the
  braking deceleration ``b = max(0, -f_x - a_0)`` beyond the driving resistances ``a_0``): the
  odometry is short by ``v k b`` -> along-track innovation on ``v b`` (the estimator's ``b``)
  with intercept and time as nuisance regressors (positive slope when unmodelled). Size: the
  profile of ``k`` (physically ``(1 - front brake share) m / C_x,rear``).

The regression slopes are attenuated by the filter (it pulls its pose towards the fixes with a
time constant of tens of seconds), so they rank the effects but do not size them. The size of
an effect is estimated by :func:`profile_scan`: re-run the estimator with the effect switched on
at a few values and take the minimum of a parabola through the innovation negative
log-likelihood ``sum_k 0.5 (NIS_k + log det S_k)`` (prediction-error decomposition, Schweppe
1965), which is what the switched-on model is judged by. :func:`assess` combines both: the model
is consistent when the residual tests pass and no switchable effect improves the likelihood
significantly (likelihood-ratio score below :data:`SCORE_THRESHOLD`).

Gyro bias is not in this library: on a drive with free axles the radius estimator does not use
the gyro for the heading (the IMU feeds its acceleration gates, the load transfer and the axle
check; the heading only while the check finds the rear axle locked), so a gyro bias cannot
enter its model
(``tests/evaluation/test_residuals.py::test_gyro_bias_is_not_attributed``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.special import chdtri

from tire_estimation.core.arrays import F64
from tire_estimation.core.geodesy import LocalTangentPlane
from tire_estimation.core.radius import effects as radius_effects
from tire_estimation.core.radius.effects import BY_NAME, Effect
from tire_estimation.core.radius.model import RL, RR
from tire_estimation.evaluation import agreement
from tire_estimation.evaluation.metrics import innovation_tests, ljung_box
from tire_estimation.sim.streams import GnssStream, WheelSpeedStream

#: |t| of an effect's regression above which the effect is reported (decimated samples).
SCORE_THRESHOLD = 4.0
#: The innovations are decimated to this spacing for the t statistics and whiteness test, s
#: (the correct-model innovations of a 10 Hz fix stream are correlated over a few fixes by the
#: slowly varying GNSS error; 1 s spacing keeps the effective sample count honest).
DECIMATION_S = 1.0
#: ... and to at least this many fix periods (the median interval of the fixes): the filter
#: corrects its pose over a few fixes at any rate. 1-Hz fixes without the Doppler velocity,
#: 3 clean drives: cross-track innovations 1 s apart correlated (Ljung-Box p 7e-6 to 1.5e-4),
#: 5 s apart white (p 0.29-0.87)
DECIMATION_FIXES = 5
#: A mean NIS below its 95 % band fails the verdict only when it is also below this share of
#: its expectation (the dimension, 2): the fixes' stated covariance (with the modelled GNSS
#: error) is then at least four times their scatter, their std at least twice. A smaller
#: overstatement leaves the reported std conservative by less than that factor.
NIS_LOW_MATERIAL_SHARE = 0.25


#: the candidate effects: every switchable effect of the estimator (its config field, scan grid,
#: regressor and words are the :class:`~tire_estimation.core.radius.effects.Effect`'s own)
EFFECTS: tuple[Effect, ...] = radius_effects.EFFECTS


def _smooth_derivative(t_s: F64, x: F64, window_s: float = 1.0) -> F64:
    """d x / d t by central differences over about ``window_s``."""
    if t_s.size < 3:
        return np.zeros_like(x)
    dt = float(np.median(np.diff(t_s)))
    h = max(1, round(0.5 * window_s / max(dt, 1e-6)))
    idx = np.arange(t_s.size)
    lo = np.clip(idx - h, 0, t_s.size - 1)
    hi = np.clip(idx + h, 0, t_s.size - 1)
    den = np.where(hi > lo, t_s[hi] - t_s[lo], 1.0)
    return np.where(hi > lo, (x[hi] - x[lo]) / den, 0.0)


def regressors_at(
    innov_t_ns: NDArray[np.int64],
    trace_t_ns: NDArray[np.int64],
    pose: F64,
    speed_m_s: F64,
    wheel_yaw_rad: F64 | None = None,
) -> dict[str, F64]:
    """Candidate regressors at the innovation times from the estimator's own trace.

    The yaw rate is the derivative over about a second of ``wheel_yaw_rad`` (per trace sample,
    the heading the wheel speeds alone turn through, eq. 6b); without it, of the estimated
    heading. The heading after each fix carries that fix's correction, which follows its
    innovation: regressed on that derivative, the cross-track innovations of clean
    positions-only drives showed a slope on ``v a_y`` of one sign (|t| 4.1 / 5.4 on two 10-min
    drives; 0.1 / 1.9 on the true yaw rate), read as a load-dependent radius.
    """
    t_tr = (trace_t_ns - trace_t_ns[0]) * 1e-9
    t_in = (innov_t_ns - trace_t_ns[0]) * 1e-9
    yaw = np.unwrap(pose[:, 2])
    turned = yaw
    if wheel_yaw_rad is not None and wheel_yaw_rad.shape == trace_t_ns.shape:
        turned = wheel_yaw_rad
    yaw_rate = _smooth_derivative(t_tr, turned)
    ax = _smooth_derivative(t_tr, speed_m_s)
    v = np.interp(t_in, t_tr, speed_m_s)
    r = np.interp(t_in, t_tr, yaw_rate)
    return {
        "speed": v,
        "speed^2": v**2,
        "longitudinal_acceleration": np.interp(t_in, t_tr, ax),
        "lateral_acceleration": v * r,
        "yaw_rate": r,
        "heading": np.interp(t_in, t_tr, yaw),
        "time": t_in,
    }


def _ols(x: F64, y: F64) -> tuple[F64, F64, float]:
    """Least squares ``y = x b``: coefficients, their std errors, R^2."""
    b, *_ = np.linalg.lstsq(x, y, rcond=None)
    res = y - x @ b
    dof = max(y.size - x.shape[1], 1)
    s2 = float(res @ res) / dof
    cov = s2 * np.linalg.pinv(x.T @ x)
    se = np.sqrt(np.maximum(np.diag(cov), 1e-300))
    tss = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(res @ res) / tss if tss > 0 else 0.0
    return b, se, r2


def _slope_beyond_time(x: F64, y: F64, ones: F64, t: F64) -> tuple[float, float]:
    """Slope of ``y`` on ``x`` with an intercept and a time trend, and its t statistic."""
    b, se, _ = _ols(np.column_stack([ones, t, x]), y)
    return float(b[2]), float(b[2] / se[2])


def decimation_s(fix_t_ns: NDArray[np.int64]) -> float:
    """The innovations' spacing, s: :data:`DECIMATION_S`, or :data:`DECIMATION_FIXES` fix
    periods (the median interval of ``fix_t_ns``) when longer."""
    if len(fix_t_ns) < 2:
        return DECIMATION_S
    period_s = float(np.median(np.diff(np.asarray(fix_t_ns, dtype=np.int64)))) * 1e-9
    return max(DECIMATION_S, DECIMATION_FIXES * period_s)


def _decimation(t_s: F64, spacing_s: float) -> NDArray[np.intp]:
    """Indices keeping about one sample per ``spacing_s``."""
    if t_s.size == 0:
        return np.zeros(0, dtype=np.intp)
    keep = [0]
    for k in range(1, t_s.size):
        if t_s[k] - t_s[keep[-1]] >= spacing_s - 1e-6:
            keep.append(k)
    return np.asarray(keep, dtype=np.intp)


def analyze(
    innov_t_ns: NDArray[np.int64],
    innov_m: F64,
    innov_cov_m2: F64,
    nis: F64,
    accepted: NDArray[np.bool_],
    trace_t_ns: NDArray[np.int64],
    pose: F64,
    speed_m_s: F64,
    min_speed_m_s: float = 1.0,
    road_grade_rad: F64 | None = None,
    rear_brake_decel_m_s2: F64 | None = None,
    sensor_agreement: Mapping[str, Any] | None = None,
    since_t_ns: int | None = None,
    wheel_yaw_rad: F64 | None = None,
) -> dict[str, Any]:
    """The ``residuals`` block of metrics.json: consistency tests, regressions, ranked effects.

    Returns ``{"consistent", "tests", "suspected_effects"}``; the effects are ranked by the
    |t| statistic of their signature (decimated innovations), most likely first, and empty
    when the run is consistent. ``estimate`` is the (filter-attenuated) regression size; use
    :func:`profile_scan` for a calibrated size. ``road_grade_rad`` (per trace sample, the
    estimator's online grade) enables the ``road_grade`` signature, ``rear_brake_decel_m_s2``
    (per trace sample, the estimator's braking deceleration) the ``rear_brake_slip`` one.
    ``sensor_agreement`` (:func:`~tire_estimation.evaluation.agreement.analyze`) replaces the
    innovation signature of each effect it tested (wheel-speed time offset, velocity latency,
    speed- and load-dependent radius, brake slip, lateral lever arm) by its own: a size from
    the sensors, not attenuated by the filter, significant only when it also matters
    (``tests.agreement``). Fixes stamped before ``since_t_ns`` (the estimator's latest change
    to its own model, ``RadiusEstimate.model_change_t_ns``) are left out: a model no longer in
    use predicted them (``tests.fixes_before_model_change``). ``wheel_yaw_rad`` (per trace
    sample, the heading the wheel speeds turn through) gives the regressors their yaw rate
    (:func:`regressors_at`).
    """
    skipped = 0
    if since_t_ns is not None:
        later = innov_t_ns >= since_t_ns
        skipped = int(np.count_nonzero(~later))
        innov_t_ns, innov_m, innov_cov_m2 = innov_t_ns[later], innov_m[later], innov_cov_m2[later]
        nis, accepted = nis[later], accepted[later]
    base = innovation_tests(innov_m, innov_cov_m2, nis, accepted)
    base.pop("consistent", None)
    if since_t_ns is not None:
        base["fixes_before_model_change"] = skipped
    if trace_t_ns.size < 3:
        return _untested(base)
    ok = accepted & np.isfinite(nis) & (innov_t_ns >= trace_t_ns[0]) & (nis > 0)
    reg = regressors_at(innov_t_ns[ok], trace_t_ns, pose, speed_m_s, wheel_yaw_rad)
    if road_grade_rad is not None and road_grade_rad.shape == trace_t_ns.shape:
        t_in = (innov_t_ns[ok] - trace_t_ns[0]) * 1e-9
        t_tr = (trace_t_ns - trace_t_ns[0]) * 1e-9
        # odometry excess rate of the slope distance over the horizontal one
        reg["speed*(1-cos(grade))"] = reg["speed"] * (
            1.0 - np.cos(np.interp(t_in, t_tr, road_grade_rad))
        )
    if rear_brake_decel_m_s2 is not None and rear_brake_decel_m_s2.shape == trace_t_ns.shape:
        t_in = (innov_t_ns[ok] - trace_t_ns[0]) * 1e-9
        t_tr = (trace_t_ns - trace_t_ns[0]) * 1e-9
        # odometry deficit rate of the braked rear wheels (per unit slip coefficient k)
        reg["speed*brake_decel"] = reg["speed"] * np.interp(t_in, t_tr, rear_brake_decel_m_s2)
    ok_idx = np.flatnonzero(ok)
    moving = reg["speed"] >= min_speed_m_s
    reg = {k: v[moving] for k, v in reg.items()}
    nu = innov_m[ok_idx[moving]]
    if nu.shape[0] < 20:
        return _untested(base)
    psi = reg["heading"]
    c, s = np.cos(psi), np.sin(psi)
    along = c * nu[:, 0] + s * nu[:, 1]
    cross = -s * nu[:, 0] + c * nu[:, 1]
    spacing_s = decimation_s(innov_t_ns)
    keep = _decimation(reg["time"], spacing_s)
    n = int(keep.size)

    tests: dict[str, Any] = dict(base)
    tests["along_track_mean_m"] = float(np.mean(along))
    tests["cross_track_mean_m"] = float(np.mean(cross))
    tests["along_track_rms_m"] = float(np.sqrt(np.mean(along**2)))
    tests["cross_track_rms_m"] = float(np.sqrt(np.mean(cross**2)))
    # whiteness of the decimated along/cross innovations, normalized by their own spread
    lags = min(10, max(1, n // 5))
    q_a, p_a = ljung_box(along[keep], lags)
    q_c, p_c = ljung_box(cross[keep], lags)
    tests["decimation_s"] = spacing_s
    tests["ljung_box_decimated"] = {
        "n": n,
        "lags": lags,
        "p_along": p_a,
        "p_cross": p_c,
        "q_along": q_a,
        "q_cross": q_c,
    }
    # single-regressor fits with intercept of each component on each candidate (standardized
    # slope t statistics on the decimated samples)
    regs: dict[str, dict[str, dict[str, float]]] = {"along_track": {}, "cross_track": {}}
    for comp, y in (("along_track", along), ("cross_track", cross)):
        for name, x in reg.items():
            xd = x[keep]
            if np.std(xd) <= 1e-12:
                continue
            b, se, r2 = _ols(np.column_stack([np.ones(n), xd]), y[keep])
            regs[comp][name] = {"slope": float(b[1]), "t": float(b[1] / se[1]), "r2": r2}
    tests["regressions"] = regs

    effects: list[dict[str, Any]] = []
    # time delays: the filter absorbs the slowly varying offset -v tau into its position, what
    # stays in the innovation is roughly its rate, -a tau (high-passed); fit along-track on
    # [1, time, a_x] (intercept and time absorb the convergence ramp of the radii)
    o = np.ones(n)
    tt = reg["time"][keep]
    axd = reg["longitudinal_acceleration"][keep]
    if np.std(axd) > 1e-3:
        b, se, _ = _ols(np.column_stack([o, tt, axd]), along[keep])
        slope, t = float(b[2]), abs(float(b[2] / se[2]))
        tests["along_track_on_time_and_ax"] = {"slope_ax": slope, "t_ax": float(b[2] / se[2])}
        effects.append(_effect("gnss_latency", t if slope < 0 else 0.0, None))
        effects.append(_effect("wheel_speed_time_offset", t if slope > 0 else 0.0, None))
    # lever arm: [nu_e; nu_n] = [cos -sin; sin cos] [a_x; a_y] + [c_e; c_n]
    ce, se_ = c[keep], s[keep]
    z = np.zeros(n)
    x_la = np.vstack([np.column_stack([ce, -se_, o, z]), np.column_stack([se_, ce, z, o])])
    y_la = np.concatenate([nu[keep, 0], nu[keep, 1]])
    if np.ptp(psi[keep]) > 0.2:
        b, se, _ = _ols(x_la, y_la)
        t_la = float(np.hypot(b[0] / se[0], b[1] / se[1]))
        effects.append(_effect("gnss_lever_arm", t_la, float(b[0]), extra={"y_m": float(b[1])}))
        tests["lever_arm_fit_m"] = [float(b[0]), float(b[1])]
    else:
        effects.append(_effect("gnss_lever_arm", 0.0, None))
    # speed^2 beyond speed
    v = reg["speed"][keep]
    if np.std(v) > 0.2:
        b, se, _ = _ols(np.column_stack([o, tt, v, v**2]), along[keep])
        effects.append(_effect("radius_speed_dependence", abs(float(b[3] / se[3])), None))
    # load-dependent radius: yaw-rate error ~ c v a_y -> cross-track on v a_y beyond time
    vay = v * reg["lateral_acceleration"][keep]
    if np.std(vay) > 1e-3:
        slope, t_load = _slope_beyond_time(vay, cross[keep], o, tt)
        tests["cross_track_on_time_and_v_ay"] = {"slope": slope, "t": t_load}
        effects.append(_effect("radius_load_dependence", abs(t_load), None))
    # road grade: along-track on v (1 - cos grade) beyond time (negative when unmodelled)
    if "speed*(1-cos(grade))" in reg:
        xg = reg["speed*(1-cos(grade))"][keep]
        if np.std(xg) > 1e-6:
            slope, t_grade = _slope_beyond_time(xg, along[keep], o, tt)
            tests["along_track_on_time_and_grade"] = {"slope": slope, "t": t_grade}
            effects.append(_effect("road_grade", -t_grade if t_grade < 0 else 0.0, None))
    # rear brake slip: along-track on v b beyond time (positive when unmodelled)
    if "speed*brake_decel" in reg:
        xb = reg["speed*brake_decel"][keep]
        if np.std(xb) > 1e-6:
            slope, t_brake = _slope_beyond_time(xb, along[keep], o, tt)
            tests["along_track_on_time_and_brake"] = {"slope": slope, "t": t_brake}
            effects.append(_effect("rear_brake_slip", max(t_brake, 0.0), None))
    if sensor_agreement is not None:
        tests["agreement"] = dict(sensor_agreement)
        effects = _with_agreement(effects, sensor_agreement)
    # the effects that matter first, each group by score
    effects.sort(key=lambda e: (not e.get("material", True), -e["score"]))
    nis_ok = _mean_nis_ok(base)
    white = bool(p_a > 0.01 and p_c > 0.01)
    significant = [e for e in effects if e["score"] >= SCORE_THRESHOLD and e.get("material", True)]
    tests["mean_nis_ok"] = nis_ok
    tests["white_decimated"] = white
    tests["score_threshold"] = SCORE_THRESHOLD
    consistent = bool(nis_ok and white and not significant)
    return {
        "consistent": consistent,
        "tests": tests,
        "suspected_effects": [] if consistent else significant or effects[:1],
    }


def _mean_nis_ok(base: Mapping[str, Any]) -> bool:
    """Whether the mean NIS of the accepted fixes fits the noise model: at most the upper 95 %
    bound (above it the model misses something, or the stated covariance is too small), and
    not materially below the lower bound (:data:`NIS_LOW_MATERIAL_SHARE`: the stated
    covariance far larger than the fixes' scatter). True without a mean NIS."""
    if "mean_nis_bounds_95" not in base:
        return True
    lo, hi = base["mean_nis_bounds_95"]
    mean = float(base["mean_nis"])
    too_low = mean < lo and mean < NIS_LOW_MATERIAL_SHARE * 2.0
    return bool(mean <= hi and not too_low)


def _with_agreement(
    effects: list[dict[str, Any]], agreement: Mapping[str, Any]
) -> list[dict[str, Any]]:
    """``effects`` with the signature of every effect the sensor agreement tested replaced by
    the agreement's (score ``|t|``, its size, ``material`` when it matters)."""
    found: dict[str, dict[str, Any]] = {}
    for relation in ("speed", "yaw_rate", "position"):
        for name, fit in agreement.get(relation, {}).items():
            if not isinstance(fit, dict):
                continue
            fit = dict(fit, relation=relation)
            if name == "time_alignment":
                # wheels late (d > 0) or the velocity late (d < 0): one regressor, two effects
                late, other = (
                    ("wheel_speed_time_offset", "gnss_velocity_latency")
                    if fit["estimate"] >= 0.0
                    else ("gnss_velocity_latency", "wheel_speed_time_offset")
                )
                found[late] = dict(fit, estimate=abs(fit["estimate"]))
                found[other] = dict(fit, t=0.0, significant=False)
            else:
                found[name] = fit
    out = [e for e in effects if e["effect"] not in found]
    for name, fit in found.items():
        eff = _effect(name, abs(fit["t"]), fit["estimate"])
        eff["source"] = "sensor agreement"
        eff["relation"] = fit["relation"]
        eff["relative_rms"] = fit["relative_rms"]
        eff["material"] = bool(fit["significant"] or abs(fit["t"]) < SCORE_THRESHOLD)
        out.append(eff)
    return out


def _untested(base: dict[str, Any]) -> dict[str, Any]:
    """Too few innovations while moving for the effect regressions: the verdict of the whole-run
    tests alone (mean NIS, whiteness of the normalized innovations), or None (not tested) when
    even those had too few innovations."""
    tests = dict(base)
    tests["note"] = "too few innovations while moving to test for effects"
    if "mean_nis" not in base:
        return {"consistent": None, "tests": tests, "suspected_effects": []}
    tests["mean_nis_ok"] = _mean_nis_ok(base)
    tests["white_normalized"] = bool(
        base["ljung_box_p_east"] > 0.01 and base["ljung_box_p_north"] > 0.01
    )
    consistent = tests["mean_nis_ok"] and tests["white_normalized"]
    return {"consistent": consistent, "tests": tests, "suspected_effects": []}


#: what disagrees, per relation of the sensor agreement
_AGREEMENT_WORDS = {
    "speed": "the wheel speeds disagree with the GNSS velocity",
    "yaw_rate": "the rear wheel-speed difference disagrees with the gyro",
    "position": "the fixes disagree with the integrated GNSS velocity",
}


def explain(report: Mapping[str, Any]) -> list[str]:
    """The verdict of an :func:`analyze` (or :func:`assess`) report in plain words: one line
    per failed test, the most likely effect first; ``[]`` when the run is consistent."""
    if report.get("consistent") is not False:
        return []
    tests = report.get("tests", {})
    lines: list[str] = []
    for eff in report.get("suspected_effects", []):
        words = BY_NAME[eff["effect"]].words if eff["effect"] in BY_NAME else eff["effect"]
        if eff["score"] >= SCORE_THRESHOLD and eff.get("source") == "sensor agreement":
            e = BY_NAME[eff["effect"]]
            what = _AGREEMENT_WORDS.get(eff.get("relation", ""), "the sensors disagree")
            moved = ""
            if eff["effect"] == "gnss_lever_arm_y":
                # what it matters by (agreement.MATERIAL_LEVER_ARM_M): the pose it moves
                moved = f"the published pose {abs(eff['estimate']):.2f} m to the side, "
            lines.append(
                f"{what} as {words} would make them: score {eff['score']:.1f} (significant from "
                f"{SCORE_THRESHOLD:g}), sized {eff['estimate']:.3g} {e.unit} "
                f"(`radius.{e.config_field}`), {moved}{100 * eff['relative_rms']:.3f} % of the "
                "speed, RMS"
            )
        elif eff["score"] >= SCORE_THRESHOLD:
            lines.append(
                f"the residuals follow a pattern of {words}: score {eff['score']:.1f} "
                f"(significant from {SCORE_THRESHOLD:g}); `--rank-effects --write-config FILE` "
                "sizes it"
            )
        else:
            lines.append(
                f"no known effect is significant; the closest is {words} (score "
                f"{eff['score']:.1f}, significant from {SCORE_THRESHOLD:g})"
            )
    if tests.get("mean_nis_ok") is False:
        lo, hi = tests["mean_nis_bounds_95"]
        mean = float(tests["mean_nis"])
        if mean > hi:
            lines.append(
                f"the fixes disagree with the model by more than their stated accuracy (mean "
                f"NIS {mean:.2f}, at most {hi:.2f} expected): a missing effect, or a fix "
                "covariance that is too small"
            )
        else:
            # E[NIS] = 2 (the dimension) when the predicted innovation covariance is right
            lines.append(
                f"the fixes scatter far less than the filter predicts (mean NIS {mean:.2f}, at "
                f"least {lo:.2f} expected: 1/{2.0 / max(mean, 1e-9):.0f} of the predicted "
                "variance): the fix covariance overstates their error, or their error is mostly "
                "slowly varying (the share radius.gnss_bias_fraction models, at most 0.9); the "
                "filter weighs the fixes less than it could and the reported radius std may be "
                "too large"
            )
    if tests.get("white_decimated") is False:
        lb = tests.get("ljung_box_decimated", {})
        lines.append(
            "the position residuals are correlated over seconds (Ljung-Box p "
            f"{lb.get('p_along', float('nan')):.1g} along track, "
            f"{lb.get('p_cross', float('nan')):.1g} across): something the model lacks drifts "
            "slowly, e.g. a time offset, a lever arm, or a GNSS error that wanders faster than "
            "radius.gnss_bias_time_constant_s"
        )
    if tests.get("white_normalized") is False:
        lines.append(
            "the position residuals are correlated in time (Ljung-Box p "
            f"{tests['ljung_box_p_east']:.1g} east, {tests['ljung_box_p_north']:.1g} north): "
            "something the model lacks drifts slowly"
        )
    if tests.get("likelihood_ratio_ok") is False and not report.get("suspected_effects"):
        lines.append("an effect improves the likelihood significantly (see ranked_effects)")
    return lines


def _effect(
    name: str, score: float, estimate: float | None, extra: dict[str, float] | None = None
) -> dict[str, Any]:
    eff = BY_NAME[name]
    out: dict[str, Any] = {
        "effect": name,
        "score": float(score),
        "estimate": estimate,
        "unit": eff.unit,
        "regressor": eff.regressor,
    }
    if extra:
        out.update(extra)
    return out


def analyze_trace(trace: Any) -> dict[str, Any]:
    """:func:`analyze` on a :class:`~tire_estimation.evaluation.runner.RadiusTrace`, with the
    sensor agreement of its record when it has one."""
    a = trace.arrays()
    params = getattr(trace, "agreement_params", None) or {}
    rows = a.get("agreement_rows")
    agree = None
    if params and rows is not None and rows.shape[0] > 0:
        agree = agreement.analyze(np.asarray(rows, dtype=float), params, SCORE_THRESHOLD)
    return analyze(
        np.asarray(trace.innov_t_ns, dtype=np.int64),
        a["innov_m"],
        a["innov_cov_m2"],
        a["nis"],
        a["accepted"],
        a["t_ns"],
        a["pose"],
        a["speed_m_s"],
        road_grade_rad=a.get("road_grade_rad"),
        rear_brake_decel_m_s2=a.get("rear_brake_decel_m_s2"),
        sensor_agreement=agree,
        since_t_ns=getattr(trace, "model_change_t_ns", None),
        wheel_yaw_rad=a.get("wheel_yaw_rad"),
    )


def _runs(trace: Any) -> list[Any]:
    """``trace`` as a list of traces (a sequence of runs, or one run)."""
    return list(trace) if isinstance(trace, (list, tuple)) else [trace]


#: NIS a gated GNSS velocity adds to the NLL: the estimator's default gate, chi-square(2) at
#: ``gnss_gate_probability`` 0.9999
VELOCITY_NIS_CAP = float(chdtri(2, 1.0 - 0.9999))


def neg_log_likelihood(trace: Any, skip_s: float = 10.0) -> float:
    """Mean innovation negative log-likelihood ``0.5 (NIS + log det S)`` of the accepted fixes
    after ``skip_s`` seconds (prediction-error decomposition of the likelihood), per fix.

    When the run used the GNSS velocity, the NLL of its velocity innovations after ``skip_s``
    is added (the likelihood of all measurements, still divided by the number of fixes), so
    that an effect on the velocity (its latency) is judged by the same objective. Every
    velocity the estimator computed an innovation for counts, gated ones with their NIS capped
    at :data:`VELOCITY_NIS_CAP` (a model that gates more of them must not look better for it).

    ``trace`` may be a list/tuple of runs of the same data with independent filter seeds: the
    NLL is then their mean, which reduces the Monte-Carlo noise of the particle filter's
    likelihood estimate (the profile of :func:`rank_effects` is then smoother).
    """
    runs = _runs(trace)
    if len(runs) > 1:
        return float(np.mean([neg_log_likelihood(r, skip_s) for r in runs]))
    trace = runs[0]
    a = trace.arrays()
    t = np.asarray(trace.innov_t_ns, dtype=np.int64)
    ok = a["accepted"] & (a["nis"] > 0)
    if t.size:
        ok &= (t - t[0]) * 1e-9 >= skip_s
    if not ok.any():
        return float("inf")
    logdet = np.linalg.slogdet(a["innov_cov_m2"][ok])[1]
    total = float(np.sum(0.5 * (a["nis"][ok] + logdet)))
    tv = a["vel_t_ns"]
    if tv.size:
        vok = (tv - t[0]) * 1e-9 >= skip_s
        if vok.any():
            vdet = np.linalg.slogdet(a["vel_innov_cov_m2_s2"][vok])[1]
            vnis = np.minimum(a["vel_nis"][vok], VELOCITY_NIS_CAP)
            total += float(np.sum(0.5 * (vnis + vdet)))
    return total / int(ok.sum())


def profile_scan(
    objective: Callable[[float], float], values: Sequence[float]
) -> tuple[float, dict[float, float]]:
    """Minimize ``objective`` over ``values`` and refine with a parabola through the best point
    and its neighbours. Returns the minimizer and the evaluated points."""
    vals = sorted(float(v) for v in values)
    f = {v: float(objective(v)) for v in vals}
    k = int(np.argmin([f[v] for v in vals]))
    if 0 < k < len(vals) - 1:
        x = np.array(vals[k - 1 : k + 2])
        y = np.array([f[v] for v in x])
        a2, a1, _ = np.polyfit(x, y, 2)
        if a2 > 0:
            return float(np.clip(-a1 / (2 * a2), x[0], x[2])), f
    return vals[k], f


#: knot spacing of the heading correction of :func:`speed_dependence_fit`, s (the estimator's
#: heading error varies over the filter's time constant, tens of seconds)
SPEED_FIT_KNOT_S = 5.0


def _interp_columns(t: F64, tp: F64, fp: F64) -> F64:
    """``np.interp`` of every column of ``fp`` (M, C) from ``tp`` (M,) to ``t`` (any shape)."""
    idx = np.clip(np.searchsorted(tp, t, side="right") - 1, 0, tp.size - 2)
    w = np.clip((t - tp[idx]) / (tp[idx + 1] - tp[idx]), 0.0, 1.0)[..., None]
    return (1.0 - w) * fp[idx] + w * fp[idx + 1]


def _cumtrapz(t: F64, f: F64) -> F64:
    """Cumulative trapezoid integral of ``f`` (M, C) over ``t`` (M,), 0 at ``t[0]``."""
    inc = 0.5 * (f[1:] + f[:-1]) * np.diff(t)[:, None]
    return np.vstack([np.zeros((1, f.shape[1])), np.cumsum(inc, axis=0)])


def speed_dependence_fit(
    trace: Any,
    wheel_speeds: WheelSpeedStream,
    gnss: GnssStream,
    nominal_radius_m: float,
    rear_brake_slip_s2_per_m: float = 0.0,
    antenna_xy_m: tuple[float, float] = (0.0, 0.0),
    knot_s: float = SPEED_FIT_KNOT_S,
    skip_s: float = 10.0,
) -> dict[str, float]:
    """Direct estimate of ``k`` of ``r = r0 + k v^2`` from the fixes and the rear wheel speeds.

    Batch least squares over the whole run (``trace`` of the estimator run *without* the
    effect: its heading, braking deceleration and ENU origin are used) with a constant ``r0``,
    so that every fix constrains the distance travelled since the start; the particle filter
    lets its radii random-walk and forgets, which is why its likelihood profile is flat in
    ``k``. Model (first order in the small terms, rear axle = ``base_link``)::

        v_w   = r_nom (w_rl + w_rr) / 2 / (1 - k_b b)       (declared rear brake slip)
        v     = w (r0 + k v^2) ~ v_w (1 + dr / r_nom + k v_w^2 / r_nom),  dr = r0 - r_nom
        psi   = psi_hat + dpsi(t),  dpsi(t) = sum_j theta_j phi_j(t)   (hat functions, knots
                every ``knot_s``: the estimator's slowly varying heading error)
        y_i   = fix_i - R(psi_hat_i) a - P0(t_i)
              = c + dr P1(t_i) + k P2(t_i) + sum_j theta_j Q_j(t_i) + e_i,
        P0 = int v_w u,  P1 = int v_w u / r_nom,  P2 = int v_w^3 u / r_nom,
        Q_j = int phi_j v_w J u,   u = (cos psi_hat, sin psi_hat),  J u = (-sin, cos)

    (integrals from ``skip_s`` after the first trace sample; ``c`` the start position). A second
    pass takes ``v^2`` in ``P2 = int v_w v^2 u / r_nom`` from the first solution. The fixes the
    estimator rejected are left out; the GNSS error is taken as white (ordinary least squares,
    standard errors from the residual variance). The other switchable effects are taken as off
    (except the antenna offset ``antenna_xy_m`` and the rear brake slip).

    Returns ``estimate`` (k, m/(m/s)^2), ``std``, ``t`` = estimate / std, ``radius_offset_m``
    (dr) and ``radius_offset_std_m``, ``residual_rms_m`` (per axis) and ``n_fixes``.
    """
    a = trace.arrays()
    t_tr = a["t_ns"]
    if t_tr.size < 3 or trace.origin_lla is None:
        return {"estimate": 0.0, "std": float("inf"), "t": 0.0, "n_fixes": 0.0}
    t0 = int(t_tr[0]) + round(skip_s * 1e9)
    t1 = int(t_tr[-1])
    tr_s = (t_tr - t0) * 1e-9
    yaw = np.unwrap(a["pose"][:, 2])
    # wheel samples of the fit interval, s from t0
    keep_w = (wheel_speeds.t_ns >= t0) & (wheel_speeds.t_ns <= t1)
    tw = (wheel_speeds.t_ns[keep_w] - t0) * 1e-9
    om = wheel_speeds.wheel_speed_rad_s[keep_w]
    v_w = 0.5 * nominal_radius_m * (om[:, RL] + om[:, RR])
    decel = a.get("rear_brake_decel_m_s2")
    if rear_brake_slip_s2_per_m and decel is not None and decel.shape == t_tr.shape:
        # braked rear wheel: w r = v (1 - k_b b)  ->  v = v_w / (1 - k_b b)
        kappa = np.maximum(-0.5, -rear_brake_slip_s2_per_m * np.interp(tw, tr_s, decel))
        v_w = v_w / (1.0 + kappa)
    psi = np.interp(tw, tr_s, yaw)
    u = np.column_stack([np.cos(psi), np.sin(psi)])
    ju = np.column_stack([-u[:, 1], u[:, 0]])
    # fixes inside the interval that the estimator accepted, in its ENU frame
    rejected = np.asarray(trace.innov_t_ns, dtype=np.int64)[~a["accepted"]]
    keep_g = (gnss.t_ns >= t0) & (gnss.t_ns <= t1) & ~np.isin(gnss.t_ns, rejected)
    if keep_g.sum() < 20 or tw.size < 3:
        return {"estimate": 0.0, "std": float("inf"), "t": 0.0, "n_fixes": float(keep_g.sum())}
    ltp = LocalTangentPlane(*trace.origin_lla)
    e, n, _u = ltp.to_enu(gnss.lat_deg[keep_g], gnss.lon_deg[keep_g], gnss.alt_m[keep_g])
    tg = (gnss.t_ns[keep_g] - t0) * 1e-9
    psi_g = np.interp(tg, tr_s, yaw)
    ax, ay = antenna_xy_m
    # fix = p + R(psi) a
    fix = np.column_stack(
        [
            np.asarray(e) - (np.cos(psi_g) * ax - np.sin(psi_g) * ay),
            np.asarray(n) - (np.sin(psi_g) * ax + np.cos(psi_g) * ay),
        ]
    )
    # cumulative integrals, columns [P0 (2), P1 (2), G0 (2), G1 (2)] with G0 = int v_w J u,
    # G1 = int s v_w J u for the hat-function columns Q_j
    f = np.hstack(
        [
            v_w[:, None] * u,
            (v_w / nominal_radius_m)[:, None] * u,
            v_w[:, None] * ju,
            (tw * v_w)[:, None] * ju,
        ]
    )
    cum = _cumtrapz(tw, f)
    c_g = _interp_columns(tg, tw, cum)  # (N, 8) at the fixes
    cum_g = cum[:, 4:8]
    # hat functions phi_j(s) = 1 - |s - tau_j| / h, knots tau_j = j h covering [0, tw[-1]];
    # Q_j(t) = [(G1(c1) - G1(tau_{j-1})) - tau_{j-1} (G0(c1) - G0(tau_{j-1}))
    #          + tau_{j+1} (G0(c2) - G0(tau_j)) - (G1(c2) - G1(tau_j))] / h
    # with c1 = clip(t, tau_{j-1}, tau_j), c2 = clip(t, tau_j, tau_{j+1}) (G = 0 before 0)
    h = float(knot_s)
    tau = h * np.arange(int(np.ceil(tw[-1] / h)) + 1)
    c1 = np.clip(tg[:, None], tau - h, tau)
    c2 = np.clip(tg[:, None], tau, tau + h)

    def g_at(t: F64) -> tuple[F64, F64]:
        gg = _interp_columns(t, tw, cum_g)
        return gg[..., 0:2], gg[..., 2:4]

    g0_1, g1_1 = g_at(c1)
    g0_a, g1_a = g_at(np.broadcast_to(tau - h, c1.shape))
    g0_2, g1_2 = g_at(c2)
    g0_b, g1_b = g_at(np.broadcast_to(tau, c1.shape))
    q = (
        (g1_1 - g1_a)
        - (tau - h)[None, :, None] * (g0_1 - g0_a)
        + (tau + h)[None, :, None] * (g0_2 - g0_b)
        - (g1_2 - g1_b)
    ) / h  # (N, knots, 2)
    n_fix = tg.size
    # stacked rows [east_i; north_i]: columns c_e, c_n, dr, k, theta_j
    x = np.zeros((n_fix, 2, 4 + tau.size))
    x[:, 0, 0] = 1.0
    x[:, 1, 1] = 1.0
    x[:, :, 2] = c_g[:, 2:4]
    x[:, :, 4:] = np.transpose(q, (0, 2, 1))
    y = (fix - c_g[:, 0:2]).reshape(-1)
    v2 = v_w**2
    for _ in range(2):
        # P2 = int v_w v^2 u / r_nom with v^2 from the previous solution (first pass: v_w^2;
        # second: v = v_w (1 + dr / r_nom + k v_w^2 / r_nom), removes the first-order bias)
        p2 = _interp_columns(tg, tw, _cumtrapz(tw, (v_w * v2 / nominal_radius_m)[:, None] * u))
        x[:, :, 3] = p2
        xm = x.reshape(2 * n_fix, -1)
        beta, *_ = np.linalg.lstsq(xm, y, rcond=None)
        v2 = (v_w * (1.0 + (beta[2] + beta[3] * v_w**2) / nominal_radius_m)) ** 2
    res = y - xm @ beta
    s2 = float(res @ res) / max(y.size - xm.shape[1], 1)
    cov = s2 * np.linalg.pinv(xm.T @ xm)
    std = float(np.sqrt(cov[3, 3]))
    k = float(beta[3])
    return {
        "estimate": k,
        "std": std,
        "t": k / std if std > 0 else 0.0,
        "radius_offset_m": float(beta[2]),
        "radius_offset_std_m": float(np.sqrt(cov[2, 2])),
        "residual_rms_m": float(np.sqrt(s2)),
        "n_fixes": float(n_fix),
    }


def chi2_mean_bounds(n: int, dof: int = 2, p: float = 0.95) -> tuple[float, float]:
    """Two-sided bounds of the mean of ``n`` chi-square(dof) variables."""
    # chi-square quantiles (chdtri(k, 1 - q) is scipy.stats.chi2.ppf(q, k))
    lo, hi = chdtri(dof * n, 1.0 - np.array([(1 - p) / 2, (1 + p) / 2])) / n
    return float(lo), float(hi)


def effect_overrides(effect: str, value: float) -> dict[str, float]:
    """Configuration fields of a re-run with ``effect`` at ``value`` (its config field plus its
    profile settings, :meth:`Effect.overrides`)."""
    return BY_NAME[effect].overrides(value)


#: scan grid of every effect (0 = not modelled), in the order of :data:`EFFECTS`
DEFAULT_GRIDS: dict[str, tuple[float, ...]] = {e.name: e.grid for e in EFFECTS}


def rank_effects(
    rerun: Callable[[str, float], Any],
    grids: dict[str, Sequence[float]] | None = None,
    baseline_nll: float | None = None,
    current: Mapping[str, float] | None = None,
) -> list[dict[str, Any]]:
    """Rank the switchable effects by their profile likelihood ratio and size them.

    ``rerun(effect, value)`` runs the estimator with ``effect`` switched on at ``value`` (the
    fields of :func:`effect_overrides`) and returns its trace. ``current`` holds the value each
    effect has in the base model (default 0, i.e. not modelled); it is added to the effect's
    grid and its NLL is ``baseline_nll``, except for an effect with profile settings, whose
    base point is re-run with them.
    For each effect the mean innovation NLL is profiled over its grid (:func:`profile_scan`);
    ``score = 2 n (NLL(current) - NLL(estimate))`` with ``n`` the number of decimated (about
    independent) fixes: a likelihood-ratio statistic, about chi-square(1) when the current
    value is right. The estimate is re-run to get the NLL at the minimizer.
    """
    grids = dict(DEFAULT_GRIDS if grids is None else grids)
    out: list[dict[str, Any]] = []
    cache: dict[tuple[str, float], float] = {}

    def nll(effect: str, value: float) -> tuple[float, Any]:
        tr = rerun(effect, value)
        return neg_log_likelihood(tr), tr

    for effect, grid in grids.items():
        traces: dict[float, Any] = {}
        base = float((current or {}).get(effect, 0.0))

        def objective(
            v: float, effect: str = effect, traces: dict[float, Any] = traces, base: float = base
        ) -> float:
            if v == base and baseline_nll is not None and not BY_NAME[effect].profile_settings:
                return baseline_nll
            f, tr = nll(effect, v)
            traces[v] = tr
            return f

        est, f = profile_scan(objective, sorted({*map(float, grid), base}))
        for v, fv in f.items():
            cache[(effect, v)] = fv
        f_est = f.get(est)
        if f_est is None:
            f_est, _tr = nll(effect, est)
        any_tr = next(iter(traces.values()), None)
        any_tr = _runs(any_tr)[0] if any_tr is not None else None
        n = 60
        if any_tr is not None and len(any_tr.innov_t_ns) > 1:
            t_ns = np.asarray(any_tr.innov_t_ns, dtype=np.int64)
            n = max(int((t_ns[-1] - t_ns[0]) * 1e-9 / decimation_s(t_ns)), 1)
        f0 = f.get(base, baseline_nll if baseline_nll is not None else f_est)
        score = max(0.0, 2.0 * n * (f0 - min(f_est, min(f.values()))))
        eff = _effect(effect, score, float(est))
        eff["nll_profile"] = {str(k): v for k, v in sorted(f.items())}
        out.append(eff)
    out.sort(key=lambda e: -e["score"])
    return out


def assess(
    trace: Any,
    rerun: Callable[[str, float], Any],
    grids: dict[str, Sequence[float]] | None = None,
    threshold: float = SCORE_THRESHOLD,
    current: Mapping[str, float] | None = None,
) -> dict[str, Any]:
    """Residual analysis of ``trace`` completed by the profile likelihood of the switchable
    effects: :func:`analyze_trace` plus :func:`rank_effects` (``rerun`` as there).

    ``trace`` (and what ``rerun`` returns) may be a list of runs with independent filter seeds
    (see :func:`neg_log_likelihood`); the residual tests use the first.

    The likelihood-ratio score of an effect is a test of the nested model (effect off) against
    the model with the effect switched on, so the run is consistent only when the residual tests
    pass *and* every score stays below ``threshold``. Returns the :func:`analyze` dictionary
    with ``ranked_effects`` (all candidates, best first) and ``tests.likelihood_ratio_ok``;
    ``suspected_effects`` are the candidates at or above the threshold when there are any.
    """
    res = analyze_trace(_runs(trace)[0])
    ranked = rank_effects(rerun, grids, baseline_nll=neg_log_likelihood(trace), current=current)
    significant = [e for e in ranked if e["score"] >= threshold]
    res["tests"]["likelihood_ratio_ok"] = not significant
    res["tests"]["likelihood_ratio_threshold"] = float(threshold)
    res["ranked_effects"] = ranked
    if significant:
        res["consistent"] = False
        res["suspected_effects"] = significant
    return res
