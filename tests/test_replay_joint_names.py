"""A robot's own joint names: one parameter file (``name_remaps``) for the replay and the node."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from tests.conftest import import_ros
from tire_estimation.bag import writer
from tire_estimation.bag.writer import write_sim_bag
from tire_estimation.core.wheels import WHEELS
from tire_estimation.errors import BagError
from tire_estimation.replay import run_replay
from tire_estimation.sim import simulate

OWN = ("front_left_wheel_joint", "front_right_wheel_joint", "rear_left_wheel_joint",
       "rear_right_wheel_joint")  # fmt: skip
REMAPS = [f"{c}={o}" for c, o in zip(WHEELS, OWN, strict=True)] + ["base_link=base_footprint"]


def _params(path: Path, remaps: list[str] | None) -> Path:
    values: dict[str, Any] = {"stiffness_enabled": False, "radius": {"n_particles": 100}}
    if remaps is not None:
        values["name_remaps"] = remaps
    path.write_text(yaml.safe_dump({"estimator_node": {"ros__parameters": values}}))
    return path


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    tmp = tmp_path_factory.mktemp("joint_names")
    sim = simulate("lane_change", seed=4, minutes=0.5)
    contract = write_sim_bag(sim, tmp / "contract")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(writer, "WHEELS", OWN)  # the same drive, recorded with the robot's names
        own = write_sim_bag(sim, tmp / "own")
    return contract, own


def _radii(bag: Path, out: Path, config: Path) -> dict[str, Any]:
    metrics = run_replay(bag, out, config_path=config, plots=False, progress=False).metrics
    return metrics["radii"]


def test_the_replay_reads_a_robots_joint_names_with_one_parameter_file(
    bags: tuple[Path, Path], tmp_path: Path
) -> None:
    contract, own = bags
    ref = _radii(contract, tmp_path / "ref", _params(tmp_path / "p0.yaml", None))
    got = _radii(own, tmp_path / "own", _params(tmp_path / "p1.yaml", REMAPS))
    assert got["final_radius_error_m"] == ref["final_radius_error_m"]
    assert np.all(np.isfinite(list(got["final_radius_error_m"].values())))
    # without the mapping: one error that names the bag's joints and the parameter
    with pytest.raises(BagError, match=r"front_left_wheel_joint.*name_remaps"):
        _radii(own, tmp_path / "unmapped", _params(tmp_path / "p2.yaml", None))


def test_a_misspelled_contract_name_is_an_error_naming_the_nearest(tmp_path: Path) -> None:
    from tire_estimation.core.wheels import Names
    from tire_estimation.errors import ConfigError

    with pytest.raises(ConfigError, match=r"name_remaps.*did you mean base_link"):
        Names.from_remaps(["base_lnk=base_footprint"])
    with pytest.raises(ConfigError, match="two joints"):
        Names.from_remaps(["wheel_fl=x", "wheel_fr=x"])


@pytest.mark.ros
def test_the_node_reads_a_robots_joint_names_and_names_its_frames(
    bags: tuple[Path, Path], tmp_path: Path
) -> None:
    rclpy, rclpy_parameter, node_mod, sensor_msgs = import_ros(
        "rclpy", "rclpy.parameter", "tire_estimation.nodes.estimator_node", "sensor_msgs.msg"
    )
    param = rclpy_parameter.Parameter
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = node_mod.EstimatorNode(
            context=context,
            parameter_overrides=[
                param("name_remaps", value=REMAPS),
                param("persistence_file", value=""),
                param("stiffness_enabled", value=False),
            ],
        )
        callbacks = {sub.topic_name: sub.callback for sub in node.subscriptions}
        published: list[Any] = []
        node.pub_odom.publish = published.append
        msg = sensor_msgs.JointState()
        msg.name = list(OWN)
        for k in range(300):
            msg.header.stamp.sec, msg.header.stamp.nanosec = 1000 + k // 100, (k % 100) * 10**7
            msg.velocity = [64.5] * 4
            callbacks["/vehicle/wheel_speeds"](msg)
        assert node.received["wheel_speeds"] == 300
        assert not any(k.startswith("wheel_speeds:") for k in node.dropped)
        assert node.names.base_frame == "base_footprint"
        assert "front_left_wheel_joint" in node.names.wheels
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
