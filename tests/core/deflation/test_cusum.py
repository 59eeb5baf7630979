"""The detector's saved state: implausible calibration values, sums and stamps are rejected
by name and change nothing; the limits follow the vehicle's nominal radius."""

from __future__ import annotations

import copy
from typing import Any

import pytest

from tests.core.deflation.test_detector import feed, plain_config
from tire_estimation.core.deflation.cusum import RADIUS_CHANGE_FACTOR, StateLimits
from tire_estimation.core.deflation.detector import DeflationDetector
from tire_estimation.errors import InputError

NOMINAL_M = 0.31  # band 15.5 mm


def _calibrated_state() -> dict[str, Any]:
    det = DeflationDetector(plain_config(), NOMINAL_M)
    feed(det, 0.0, (3e-4, -2e-4))
    feed(det, 1.0, (3e-4, -2e-4))
    for k in range(2, 6):
        feed(det, float(k), (-1e-3, -2e-4))
    state = det.state_dict()
    assert state["wheels"]["wheel_rl"]["calibrated_m"] is not None
    assert state["wheels"]["wheel_rl"]["g_m"] > 0.0
    return state


GOOD = _calibrated_state()


def _wheel(**values: Any) -> dict[str, Any]:
    state = copy.deepcopy(GOOD)
    state["wheels"]["wheel_rl"].update(values)
    return state


@pytest.mark.parametrize(
    ("state", "reason"),
    [
        (_wheel(calibrated_m=0.1), "calibrated_m=0.1 is outside"),
        (_wheel(calibrated_m=-0.1), "calibrated_m"),
        (_wheel(last_estimate_m=1e29), "last_estimate_m"),
        (_wheel(common_calibrated_m=float("inf")), "not finite"),
        (_wheel(calib_time_s=int("9" * 500)), "too large"),
        (_wheel(calib_time_s=-1.0), "calib_time_s"),
        (_wheel(calib_time_s=1e6), "exceeds driving_time_s"),
        (_wheel(calib_sum_w=1e5), "calib_sum_w"),
        (_wheel(common_sum_wx=5.0), "common_sum_wx"),
        (_wheel(g_m=-1e-3), "g_m"),
        (_wheel(g_m=10.0), "g_m"),
        (_wheel(xbar_m=0.5), "xbar_m"),
        (_wheel(threshold_m=-1.0), "threshold_m"),
        (_wheel(alarm_t_ns=-5), "alarm_t_ns"),
        (_wheel(alarm_t_ns=1 << 70), "alarm_t_ns"),
        (_wheel(tyre="x"), "unknown keys tyre"),
        ({**GOOD, "driving_time_s": -3.0}, "driving_time_s"),
        ({**GOOD, "common": {"g_m": 1e9}}, "g_m"),
        ({**GOOD, "common": {"wheel_names": [1]}}, "bad wheels"),
        ({**GOOD, "version": True}, "version"),
        ({**GOOD, "extra": 1}, "unknown keys extra"),
        ({k: v for k, v in GOOD.items() if k != "wheels"}, "lacks wheels"),
    ],
)
def test_an_implausible_state_is_rejected_and_changes_nothing(
    state: dict[str, Any], reason: str
) -> None:
    det = DeflationDetector(plain_config(), NOMINAL_M)
    before = det.state_dict()
    with pytest.raises(InputError, match=reason) as info:
        det.load_state_dict(state)
    assert info.value.kind == "bad_state"
    assert det.state_dict() == before


def test_a_valid_state_restores_and_the_band_follows_the_nominal_radius() -> None:
    det = DeflationDetector(plain_config(), NOMINAL_M)
    det.load_state_dict(GOOD)
    assert det.state_dict() == GOOD
    # 100 mm: implausible on a 0.31 m tyre (25 %: 77.5 mm), plausible when the vehicle is
    # unknown (the largest nominal radius a vehicle description allows, 1.5 m: 375 mm)
    shifted = _wheel(calibrated_m=0.1, calib_sum_wx=0.1 * GOOD["wheels"]["wheel_rl"]
                     ["calib_sum_w"], common_calibrated_m=0.1)  # fmt: skip
    with pytest.raises(InputError, match="calibrated_m"):
        DeflationDetector(plain_config(), NOMINAL_M).load_state_dict(shifted)
    unknown = DeflationDetector(plain_config())
    assert unknown.radius_error_limit_m == pytest.approx(0.375)
    unknown.load_state_dict(shifted)
    assert unknown.status().wheel("wheel_rl").calibrated_radius_error_m == pytest.approx(0.1)


def test_limits_of_each_saved_value() -> None:
    limits = StateLimits(radius_error_m=0.01, cusum_m=2.0)
    assert limits.range_of("calibrated_m") == (-0.01, 0.01)
    assert limits.range_of("raw_m") == (-RADIUS_CHANGE_FACTOR * 0.01, RADIUS_CHANGE_FACTOR * 0.01)
    assert limits.range_of("g_m") == (0.0, 2.0)
    assert limits.range_of("calib_sum_wx")[0] < -1e300
    assert limits.range_of("calib_time_s")[0] == 0.0
