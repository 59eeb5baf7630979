"""replay_topics: the truth odometry is decoded only when a lateral estimator will use it."""

from __future__ import annotations

import pytest

from tire_estimation.bag import topics as tp
from tire_estimation.bag.reader import TopicInfo
from tire_estimation.replay import replay_topics


def _infos(*present: str) -> dict[str, TopicInfo]:
    infos = {t: TopicInfo(tp.TOPIC_TYPES[t], 100) for t in present}
    infos[tp.TRUTH_ODOMETRY] = TopicInfo(tp.TOPIC_TYPES[tp.TRUTH_ODOMETRY], 100)
    infos[tp.TIRE_FORCES_TOPIC] = TopicInfo(tp.TOPIC_TYPES[tp.TIRE_FORCES_TOPIC], 0)  # empty
    return infos


RADIUS = (tp.WHEEL_SPEEDS, tp.GNSS_FIX)
LATERAL = (tp.WHEEL_SPEEDS, tp.GNSS_FIX, tp.IMU_DATA, tp.STEERING)


@pytest.mark.parametrize(
    ("present", "stiffness", "wanted"),
    [
        (RADIUS, True, False),  # no IMU / steering: no lateral estimator
        (LATERAL, False, False),  # stiffness MPF switched off
        (LATERAL, True, True),
        ((tp.VEHICLE_VELOCITY, tp.IMU_DATA, tp.STEERING), True, True),  # Revs-style bag
        ((tp.WHEEL_SPEEDS, tp.GNSS_FIX, tp.TIRE_FORCES_TOPIC), False, True),  # tyre-force KF
    ],
)
def test_truth_odometry_only_for_lateral_estimators(
    present: tuple[str, ...], stiffness: bool, wanted: bool
) -> None:
    infos = _infos(*present)
    if tp.TIRE_FORCES_TOPIC in present:
        infos[tp.TIRE_FORCES_TOPIC] = TopicInfo(tp.TOPIC_TYPES[tp.TIRE_FORCES_TOPIC], 5)
    chosen = replay_topics(infos, stiffness)
    assert (tp.TRUTH_ODOMETRY in chosen) is wanted
    assert {tp.WHEEL_SPEEDS, tp.GNSS_FIX, tp.TRUTH_FIX, tp.REFERENCE_ODOMETRY} <= set(chosen)
