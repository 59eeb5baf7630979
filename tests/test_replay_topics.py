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


def test_the_measured_velocity_only_without_wheel_speeds() -> None:
    """A bag with wheel speeds never feeds /vehicle/velocity: it is not decoded."""
    with_wheels = replay_topics(_infos(*LATERAL, tp.VEHICLE_VELOCITY), True)
    without = replay_topics(_infos(tp.VEHICLE_VELOCITY, tp.IMU_DATA, tp.STEERING), True)
    assert tp.VEHICLE_VELOCITY not in with_wheels and tp.VEHICLE_VELOCITY in without


def test_replay_feeds_the_gnss_velocity_when_switched_on(tmp_path) -> None:
    """A simulated bag with /gnss/velocity: decoded by the replay, used only with
    ``gnss_velocity_enabled`` (the radii then differ), and the MPF's estimate stays close."""
    import numpy as np

    from tire_estimation.bag.writer import write_sim_bag
    from tire_estimation.core.radius.config import RadiusEstimatorConfig
    from tire_estimation.replay import run_replay
    from tire_estimation.sim import SensorConfig, simulate

    sim = simulate(
        "ece_r64", seed=2, minutes=2.0, deflation_fraction=0.0,
        sensors=SensorConfig(gnss_velocity_enabled=True),
    )  # fmt: skip
    bag = write_sim_bag(sim, tmp_path / "bag")
    radii, errors, vel = {}, {}, {}
    for on in (False, True):
        cfg = RadiusEstimatorConfig(n_particles=200, gnss_velocity_enabled=on)
        m = run_replay(
            bag, tmp_path / f"out_{on}", config=cfg, plots=False, progress=False, stiffness=False
        ).metrics
        radii[on] = np.array(list(m["radii"]["final_radius_error_m"].values()))
        errors[on] = np.array(list(m["radii"]["final_error_vs_truth_m"].values()))
        vel[on] = m["gnss_velocity"]
    assert not np.array_equal(radii[False], radii[True])
    assert np.all(np.abs(errors[True]) < 0.5e-3), errors
    # the report says how many velocities were used and with which latency
    assert vel[False] is None
    assert vel[True]["updates"] > 100 and vel[True]["latency_s"] == 0.0
    assert vel[True]["innovations"] >= vel[True]["updates"]
    assert 0.5 < vel[True]["mean_nis"] < 3.0


def test_summary_prints_slow_real_time_factors_with_two_digits(tmp_path) -> None:
    """A replay slower than real time (e.g. with --rank-effects) must not print "0x"."""
    from tire_estimation.replay import ReplayReport

    def first_line(rtf: float) -> str:
        metrics = {
            "bag": "b", "duration_s": 60.0, "wall_s": 60.0 / rtf, "realtime_factor": rtf,
            "radii": {"final_radius_error_m": {}, "final_radius_error_std_m": {}},
            "position": {"rmse_m": None}, "residuals": {"consistent": None},
        }  # fmt: skip
        return ReplayReport(tmp_path, metrics).summary().splitlines()[0]

    assert first_line(0.37).endswith("0.37x real time)")
    assert first_line(3.04).endswith("3x real time)")
    assert first_line(212.4).endswith("212x real time)")
