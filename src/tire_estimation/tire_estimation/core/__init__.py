"""Pure-Python estimation core: no rclpy, no message packages, no rosbags.

Time is float seconds or integer nanoseconds. Arrays over particles are shaped ``(N, ...)``.
"""
