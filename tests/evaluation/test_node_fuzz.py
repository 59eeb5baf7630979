"""node_fuzz: bad messages and clock faults into both nodes, against a clean run."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import import_ros

pytestmark = pytest.mark.ros

BAG = Path(__file__).parents[2] / "bags" / "ece_r64_6min"

#: bad values in fields the nodes do not read (frame ids of the sensor inputs, the wheel
#: speeds' positions, the steering's velocities, the IMU's orientation)
UNREAD_FIELDS = {"frame_1mb", "position_nan", "position_1e308", "orientation_nan"}
STEERING_VELOCITY = {
    "velocity_nan",
    "velocity_inf",
    "velocity_1e308",
    "velocity_minus_1e308",
    "velocity_empty",
    "velocity_3",
    "velocity_100",
}


#: documented: a NaN altitude is "not reported" in ROS; the fix is used horizontally and counted
#: as ``gnss_fix:no_altitude``; the GNSS velocity's frame id is not read (ENU by contract)
BY_DESIGN = {"/gnss/fix:alt_nan", "/gnss/velocity:frame_wrong"}


def _unread(key: str) -> bool:
    topic, kind = key.split(":")
    if key in BY_DESIGN or kind in UNREAD_FIELDS:
        return True
    return topic == "/vehicle/steering" and kind in STEERING_VELOCITY


def test_bad_messages_and_clock_faults_neither_crash_nor_stop_the_nodes() -> None:
    """2,000 bad messages of every kind and five clock faults (20 s apart) into 170 s of the
    bundled drive: no crash, no non-finite output, radii within 1 mm of the clean run 60 s
    after each fault, outputs kept coming, and every bad value dropped and counted."""
    (node_fuzz,) = import_ros("tire_estimation.evaluation.node_fuzz")
    report = node_fuzz.fuzz(BAG, 2000, seed=0, seconds=170, stiffness=False, clock_every_s=20)
    assert report.bad_kinds >= 80
    assert not report.crashes
    assert not report.non_finite
    assert set(report.recovery_m) == set(node_fuzz.CLOCK_FAULTS)
    assert max(report.recovery_m.values()) <= node_fuzz.RECOVERY_TOLERANCE_M
    assert min(report.published_share.values()) >= node_fuzz.MIN_PUBLISHED_SHARE
    accepted = {key for key in report.accepted if not _unread(key)}
    assert not accepted, f"bad values used instead of dropped: {sorted(accepted)}"
    assert report.ok
