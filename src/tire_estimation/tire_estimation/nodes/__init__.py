"""Thin rclpy nodes over the pure-Python core (imports rclpy; never imported by core/)."""
