"""Vehicle and sensor simulator (pure Python and NumPy; no ROS, no rosbags)."""
