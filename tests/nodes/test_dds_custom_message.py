"""A custom tire_estimation_msgs message crosses DDS between two rclpy nodes."""

from __future__ import annotations

import time

import pytest

from tests.conftest import import_ros

pytestmark = [pytest.mark.ros, pytest.mark.serial]


def test_tire_radii_message_goes_over_dds() -> None:
    rclpy, msg_mod, executors = import_ros("rclpy", "tire_estimation_msgs.msg", "rclpy.executors")
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        pub_node = rclpy.create_node("dds_test_publisher", context=context)
        sub_node = rclpy.create_node("dds_test_subscriber", context=context)
        received: list = []
        sub_node.create_subscription(
            msg_mod.TireRadii, "/tire_estimation/tire_radii", received.append, 10
        )
        publisher = pub_node.create_publisher(msg_mod.TireRadii, "/tire_estimation/tire_radii", 10)
        executor = executors.SingleThreadedExecutor(context=context)
        executor.add_node(pub_node)
        executor.add_node(sub_node)

        sent = msg_mod.TireRadii()
        sent.header.frame_id = "base_link"
        sent.nominal_radius_m = 0.31
        sent.wheel_names = ["wheel_rl", "wheel_rr"]
        sent.radius_error_m = [0.0012, -0.0005]
        sent.radius_error_std_m = [1e-4, 2e-4]
        sent.radius_noise_std_m = [1e-5, 1e-5]
        sent.active = [True, False]
        sent.state = msg_mod.TireRadii.STATE_RUNNING

        deadline = time.monotonic() + 20.0
        while not received and time.monotonic() < deadline:
            publisher.publish(sent)
            executor.spin_once(timeout_sec=0.1)
        assert received, "no TireRadii message arrived within 20 s"
        got = received[0]
        assert list(got.wheel_names) == ["wheel_rl", "wheel_rr"]
        assert list(got.radius_error_m) == pytest.approx([0.0012, -0.0005])
        assert list(got.active) == [True, False]
        assert got.state == msg_mod.TireRadii.STATE_RUNNING
        assert got.header.frame_id == "base_link"
        executor.shutdown()
        pub_node.destroy_node()
        sub_node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
